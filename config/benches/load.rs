//! What loading costs: parsing the reference file (every key written out) into the raw
//! settings, validating them, and both together, against a baseline of parsing the same text
//! into an untyped `toml::Table` measured in the same run.
//!
//! `cargo bench -p config --bench load`

use criterion::{black_box, criterion_group, criterion_main, Criterion};

use config::{examples, Config, RawConfig};

fn load(c: &mut Criterion) {
    let text = examples::SIM;
    let mut group = c.benchmark_group("load_reference_file");
    group.bench_function("baseline_untyped_toml_table", |b| {
        b.iter(|| black_box(text).parse::<toml::Table>())
    });
    group.bench_function("parse_raw", |b| {
        b.iter(|| RawConfig::from_toml_str(black_box(text)))
    });
    let raw = RawConfig::from_toml_str(text).expect("the shipped file parses");
    group.bench_function("validate", |b| b.iter(|| black_box(&raw).validate()));
    group.bench_function("parse_and_validate", |b| {
        b.iter(|| Config::from_toml_str(black_box(text)))
    });
    group.finish();
}

criterion_group!(benches, load);
criterion_main!(benches);
