//! The soak's garbage phase, measured at the pipeline: a parked radar looking at four
//! reflectors (the soak's scene), and for 1.5 s one byte of every fifth FFT frame inverted
//! (as the soak's `Phase::Garbage` does), each frame then decoded as the driver decodes it.
//!
//! Why the soak's garbage left about 100 features (measured 2026-11-29, debug build,
//! `cargo test -p slam-node --test garbage_frames -- --ignored --nocapture`): of about 155
//! frames hit, an inverted byte anywhere mapped at most 113 features during and 1 s after
//! the phase, one in the bins 116, and one in the frame header (all refused), the FFT data
//! offset, the sweep counter, the encoder or the stamp none beyond the 4-5 of the scene.
//! An inverted bin is a one-bin spike: a noise bin v becomes 255 - v, 50-80 dB over the
//! noise. The TPP detector smooths each slot's spectrum recursively over rotations (weight
//! 0.3 on the previous scan, in dB) against a 20 dB threshold over the noise minimum, so
//! such a spike stayed above it the next rotation of the same azimuth slot: a second look
//! 0.4 s later, and `confirm_after = 2` mapped it. It was then never re-observed and was
//! retired as unrepeatable, within about 7 s.
//!
//! Now a scan more than `drop_reset_db` below a bin's smoothed level replaces the level
//! (`TppSettings::drop_reset_db`, 45 dB): anywhere 113 -> 29 features at most, the bins
//! 116 -> 40 (4 at the end, as before). The spikes that still confirm are the smaller ones
//! (under about 64 dB, whose smoothed level drops by less than 45 dB). A reset at 30 dB
//! gives 6 and 5, at 40 dB 8 and 10, but both change the README's first command
//! (`--fast`: at 30 dB the final error 0.179 -> 0.180 m and 7505 -> 7504 associations, at
//! 40 dB the mean NEES 9.01 -> 9.00; the trailing smear of strong targets the vehicle drives
//! past is reset too); at 45 dB its figures are unchanged (detections 8517 -> 8464), as are
//! the Oxford replay's.
mod support;

use bytes::BytesMut;
use protocol::{FftData, FrameDecoder, Message};
use rand::{Rng, SeedableRng};
use slam_node::pipeline::Pipeline;
use support::{still, still_radar_azimuths, still_radar_settings};

const T0_NS: u64 = 1_700_000_000_000_000_000;
const GARBAGE: (f64, f64) = (6.0, 7.5);

/// Where the inverted byte may fall: (label, first byte, end) of the frame.
fn run(label: &str, region: (usize, usize)) -> (usize, usize, usize) {
    let t0 = T0_NS as f64 * 1e-9;
    let azimuths = still_radar_azimuths(30, T0_NS); // 12 s
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let mut p = Pipeline::new(still_radar_settings(), None, None).expect("pipeline");
    let mut events = Vec::new();
    let mut next_odometry = t0;
    let (mut flipped, mut refused, mut most_after) = (0, 0, 0);
    for az in &azimuths {
        let t = az.timestamp_s - t0;
        let mut az = az.clone();
        if (GARBAGE.0..GARBAGE.1).contains(&t) && rng.gen_bool(0.2) {
            let mut frame = BytesMut::new();
            Message::FftData(FftData::new(
                az.width,
                az.sweep_counter,
                az.encoder,
                protocol::Timestamp::from_secs_f64(az.timestamp_s).expect("stamp"),
                az.bins.clone(),
            ))
            .encode(&mut frame)
            .expect("frame");
            let end = region.1.min(frame.len());
            let at = rng.gen_range(region.0..end);
            frame[at] ^= 0xff;
            flipped += 1;
            match FrameDecoder::new().decode_eof(&mut frame) {
                Ok(Some(Message::FftData(fft))) if fft.azimuth < az.geometry.encoder_size => {
                    az = radar_driver::Azimuth {
                        rotation: az.rotation,
                        ..radar_driver::Azimuth::from_fft(fft, az.geometry.clone())
                    };
                }
                _ => {
                    refused += 1;
                    continue;
                }
            }
        }
        // Odometry on the true clock (a flipped stamp does not move the vehicle's clock).
        while next_odometry <= t0 + t + 0.1 {
            p.push_odometry(still(next_odometry));
            next_odometry += 0.05;
        }
        let _ = p.process_azimuth(&az, &mut events);
        events.clear();
        if t >= GARBAGE.0 && t < GARBAGE.1 + 1.0 {
            most_after = most_after.max(p.ekf().feature_count());
        }
    }
    println!(
        "{label}: {flipped} frames flipped, {refused} refused; at most {most_after} features during and 1 s after; {} at the end",
        p.ekf().feature_count()
    );
    (flipped, refused, most_after)
}

#[test]
#[ignore = "a measurement: prints what each region of the frame costs"]
fn which_inverted_byte_maps_features() {
    run("anywhere", (0, usize::MAX));
    run("the 22-byte frame header", (0, 22));
    run("the FFT data offset", (22, 24));
    run("the sweep counter", (24, 26));
    run("the encoder", (26, 28));
    run("the stamp", (28, 36));
    run("the bins", (36, usize::MAX));
}
