//! Prints every rotation a radar sends: azimuth count, first and last encoder value, the
//! time it spans, skipped azimuths. The library alone (no configuration files, no CLI
//! crates): `cargo run --release -p radar-driver --example print_rotations -- ADDRESS`, the
//! radar's `ip:port` (or the simulator's: `cargo run --release -p sim-sensor` prints the
//! address it listens on). The address is required: the example dials no port of its own.

use radar_driver::{Driver, DriverSettings};

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let address = std::env::args()
        .nth(1)
        .ok_or("usage: print_rotations ADDRESS (the radar's ip:port)")?
        .parse()?;
    let mut settings = DriverSettings::new(address);
    // Rotations only: no azimuth stream.
    settings.handoff.azimuth_capacity = None;
    let (driver, mut streams) = Driver::with_streams(settings);
    let handle = driver.spawn();
    let mut rotations = streams.rotations.take().ok_or("no rotation stream")?;
    let stop = tokio::signal::ctrl_c();
    tokio::pin!(stop);
    loop {
        tokio::select! {
            _ = &mut stop => break,
            rotation = rotations.next() => {
                let Some(r) = rotation else { break };
                let (Some(first), Some(last)) = (r.azimuths.first(), r.azimuths.last()) else {
                    continue;
                };
                println!(
                    "rotation {:5}: {:4} azimuths, encoder {:5}..{:5}, {:.3} s, {} skipped{}",
                    r.sequence,
                    r.azimuths.len(),
                    first.encoder,
                    last.encoder,
                    last.timestamp_s - first.timestamp_s,
                    r.skipped_azimuths,
                    if r.complete { "" } else { " (partial)" }
                );
            }
        }
    }
    let exit = handle.stop().await?;
    println!(
        "{} azimuths, {} rotations",
        exit.metrics.azimuths_sent, exit.metrics.rotations_sent
    );
    Ok(())
}
