//! Invariants of whole-spectrum prediction and synthesis over random beams.

use proptest::prelude::*;
use radar_model::noise::{seeded_rng, NoiseModel};
use radar_model::spectrum::{SpectrumGeometry, SpectrumModel, SpectrumTarget};
use radar_model::Compensation;

fn targets() -> impl Strategy<Value = Vec<SpectrumTarget>> {
    prop::collection::vec((-10.0f64..250.0, -400.0f64..400.0), 0..=12).prop_map(|v| {
        v.into_iter()
            .map(|(range_m, power_db)| SpectrumTarget { range_m, power_db })
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Peaks only add power: the prediction never drops below the floor, is finite, and
    /// far from every target equals the floor.
    #[test]
    fn predictions_are_finite_and_never_below_the_floor(t in targets(), sixty in any::<bool>()) {
        let geometry = SpectrumGeometry::paper_unit();
        let constants = radar_model::RadarConstants::default();
        let comp = if sixty {
            Compensation::paper_sixty(&constants)
        } else {
            Compensation::calibrated(40.0, &constants)
        };
        let model = SpectrumModel::new(geometry, &comp, NoiseModel::default()).unwrap();
        let mut out = vec![0.0; geometry.bins];
        for expected in [false, true] {
            if expected {
                model.expected_into(&t, &mut out).unwrap();
            } else {
                model.predict_into(&t, &mut out).unwrap();
            }
            for (b, (v, f)) in out.iter().zip(model.floor_mean_db()).enumerate() {
                prop_assert!(v.is_finite());
                prop_assert!(*v >= *f);
                let r = geometry.bin_range_m(b);
                if t.iter().all(|x| (x.range_m - r).abs() > 2.0) {
                    prop_assert_eq!(*v, *f);
                }
            }
        }
    }

    /// One look is finite everywhere and, for a strong lone target, peaks within a few bins
    /// of its range.
    #[test]
    fn synthesised_looks_are_finite_and_peak_where_a_strong_target_is(
        t in targets(), seed in any::<u64>(), range in 50.0f64..190.0,
    ) {
        let geometry = SpectrumGeometry::paper_unit();
        let model =
            SpectrumModel::new(geometry, &Compensation::default(), NoiseModel::default()).unwrap();
        let mut out = vec![0.0; geometry.bins];
        model.synthesize_into(&t, &mut seeded_rng(seed), &mut out).unwrap();
        prop_assert!(out.iter().all(|v| v.is_finite()));
        let strong = [SpectrumTarget { range_m: range, power_db: 0.0 }];
        model.synthesize_into(&strong, &mut seeded_rng(seed), &mut out).unwrap();
        let (argmax, _) = out
            .iter()
            .enumerate()
            .fold((0, f64::MIN), |(bi, bv), (i, &v)| if v > bv { (i, v) } else { (bi, bv) });
        // Phase noise of 0.1 m: the peak stays within 0.75 m (7.5 sigma) of the target.
        prop_assert!((geometry.bin_range_m(argmax) - range).abs() <= 0.75);
    }
}
