use evaluation::scan::*;
use evaluation::sections::spectra::*;
use evaluation::world::World;
fn main() {
    let scene = sim_sensor::scene::shipped::load("outdoor-field").unwrap();
    let world = World::new(scene, 21, 3.0, Default::default()).unwrap();
    let (scans, mids) = render_scans(&world, 2).unwrap();
    let g = world.geometry;
    let axis = slam_node::detect::RangeAxis {
        first_bin_m: 0.0,
        bin_m: g.bin_size_m,
    };
    let comp = Variant::all()[0].compensation();
    let gain: Vec<f64> = (0..g.bins)
        .map(|b| comp.gain_db(g.bin_range_m(b)))
        .collect();
    let mut det =
        slam_node::detect::BeamDetector::new(evaluation::sections::shipped_detector(), 200);
    let mut found = Vec::new();
    let mut total = 0;
    for (i, r) in scans[0].rows.iter().enumerate() {
        found.clear();
        det.detect(i, &r.measured_db, &gain, &axis, &mut found);
        total += found.len();
    }
    println!(
        "raw {total} max {}",
        scans[0]
            .rows
            .iter()
            .flat_map(|r| r.measured_db.iter())
            .fold(0.0f64, |a, b| a.max(*b))
    );
    let obs = detect_scan(
        &scans[0],
        evaluation::sections::shipped_detector(),
        &gain,
        &axis,
        world.scene.radar.beam_width_rad,
    );
    println!("obs {}", obs.len());
    let fitted = fit_targets(&obs, &world.power, 0.0157).unwrap();
    println!("fitted {} {:?}", fitted.len(), fitted.first());
    println!("rel {:?}", relative(&mids[0], &mids[1]));
}
