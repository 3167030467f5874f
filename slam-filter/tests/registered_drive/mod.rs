//! What the motion-measurement tests share: a drive on a bicycle with odometry at 20 Hz and
//! a registration of the motion since the last mark every 0.25 s.

use radar_model::geometry::Pose2;
use radar_model::motion::{ControlInput, MotionModel};
use rand_chacha::ChaCha8Rng;
use slam_filter::{Ekf, OdometrySample, RadarBeamModel};

pub type Filter = Ekf<MotionModel, RadarBeamModel>;

pub const T0: f64 = 1_700_000_000.0;
pub const WHEELBASE_M: f64 = 2.7;

/// Drives `f` (a bicycle of [`WHEELBASE_M`], at [`T0`]) for `steps` odometry samples at 20 Hz:
/// `odometry(i, rng)` gives the true speed and steering and what the odometry reads. Every
/// fifth sample, once the filter has a mark, `register(f, true motion since the mark, rng)`
/// may give the filter a motion measurement, and the filter is marked there. The filter
/// ends predicted to the last sample's time. Returns the true pose at the end.
pub fn drive_registered(
    f: &mut Filter,
    steps: u32,
    rng: &mut ChaCha8Rng,
    mut odometry: impl FnMut(u32, &mut ChaCha8Rng) -> ((f64, f64), (f64, f64)),
    mut register: impl FnMut(&mut Filter, Pose2, &mut ChaCha8Rng),
) -> Pose2 {
    let model = MotionModel::Bicycle {
        wheelbase_m: WHEELBASE_M,
    };
    let mut truth = Pose2::new(0.0, 0.0, 0.0);
    let mut mark = truth;
    let dt = 0.05;
    for i in 0..steps {
        let t = T0 + f64::from(i) * dt;
        let ((speed, steer), (read_speed, read_steer)) = odometry(i, rng);
        f.apply_odometry(OdometrySample {
            timestamp_s: t,
            speed_mps: read_speed,
            steer_rad: read_steer,
        })
        .unwrap();
        if i % 5 == 0 {
            f.predict_to(t).unwrap();
            if f.motion_tally().is_some() {
                register(f, mark.between(&truth), rng);
            }
            f.mark_motion();
            mark = truth;
        }
        truth = model
            .predict(&truth, &ControlInput::new(speed, steer), dt)
            .unwrap();
    }
    f.predict_to(T0 + f64::from(steps) * dt).unwrap();
    truth
}
