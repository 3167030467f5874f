//! Named hard cases: no NaN, no infinity, bounded Jacobians, typed errors on bad input.

use radar_model::material::{Material, MIN_SHARE};
use radar_model::noise::{seeded_rng, NoiseModel};
use radar_model::power::{beam_powers_with_jacobian, PowerModel, PowerTarget};
use radar_model::spectrum::{
    beam_spectrum_targets, SpectrumGeometry, SpectrumModel, SpectrumTarget,
};
use radar_model::{
    features_in_beam, observe_beam, Beam, BeamFeature, BeamObservation, Compensation, ModelError,
    Pose2, SpreadingForm,
};

/// Bound on any power-row entry: range terms are at most `2 x 40/ln10 x 1/(2 dr)` = 69.5
/// dB/m per neighbour pair at dr = 0.25 m, material terms at most `20/ln10` = 8.7 dB.
const POWER_JACOBIAN_BOUND: f64 = 80.0;

fn forms() -> [PowerModel; 2] {
    [
        PowerModel::default(),
        PowerModel {
            form: SpreadingForm::Textbook,
            ..PowerModel::default()
        },
    ]
}

/// Every value finite, and every power row (each third row) bounded.
fn assert_sound(obs: &BeamObservation) {
    for z in &obs.z {
        assert!(z.range_m.is_finite() && z.bearing_rad.is_finite() && z.power_db.is_finite());
    }
    assert!(obs.jacobian.iter().all(|v| v.is_finite()));
    for i in 0..obs.z.len() {
        let row = obs.jacobian.row(3 * i + 2);
        let worst = row.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst <= POWER_JACOBIAN_BOUND, "power row {i}: {worst}");
    }
}

fn spectrum_is_finite(targets: &[SpectrumTarget]) {
    let geometry = SpectrumGeometry::paper_unit();
    let model =
        SpectrumModel::new(geometry, &Compensation::default(), NoiseModel::default()).unwrap();
    let mut out = vec![0.0; geometry.bins];
    model.predict_into(targets, &mut out).unwrap();
    assert!(out.iter().all(|v| v.is_finite()));
    model
        .synthesize_into(targets, &mut seeded_rng(1), &mut out)
        .unwrap();
    assert!(out.iter().all(|v| v.is_finite()));
}

#[test]
fn targets_at_equal_range_stay_finite_and_are_flagged_unresolvable() {
    let pose = Pose2::new(0.0, 0.0, 0.0);
    let m = Material::from_rho_alpha(0.3, 0.1).unwrap();
    // Same range, bearings 0.2 degrees apart: both inside one 1.8 degree beam.
    let feats = [
        BeamFeature {
            xy: pose.point_at(20.0, 0.0),
            material: m,
        },
        BeamFeature {
            xy: pose.point_at(20.0, 0.2f64.to_radians()),
            material: m,
        },
        BeamFeature {
            xy: pose.point_at(35.0, 0.0),
            material: m,
        },
    ];
    for model in forms() {
        let obs = observe_beam(&pose, &feats, 0.0, &model).unwrap();
        assert_sound(&obs);
        assert_eq!(obs.unresolvable, vec![true, true, false]);
        // The one behind (by index at equal range) sees the first's transmission squared,
        // and a separation regularised to dr instead of zero.
        let tau_db = 20.0 * m.shares().tau.log10();
        let gap = obs.z[0].power_db - obs.z[1].power_db;
        if model.form == SpreadingForm::Textbook {
            assert!((gap + tau_db).abs() < 1e-9, "gap {gap}");
        }
    }
}

#[test]
fn rho_plus_alpha_near_one_keeps_everything_finite() {
    let pose = Pose2::default();
    for (rho, alpha) in [(0.5, 0.5), (1.0, 0.0), (0.0, 1.0), (0.7, 0.3 - 1e-13)] {
        let opaque = Material::from_rho_alpha(rho, alpha).unwrap();
        let s = opaque.shares();
        assert!(
            s.tau >= 0.5 * MIN_SHARE && s.tau <= 2.0 * MIN_SHARE,
            "tau {}",
            s.tau
        );
        let feats = [
            BeamFeature {
                xy: [10.0, 0.0],
                material: opaque,
            },
            BeamFeature {
                xy: [30.0, 0.0],
                material: Material::from_rho_alpha(0.5, 0.1).unwrap(),
            },
        ];
        for model in forms() {
            let obs = observe_beam(&pose, &feats, 0.0, &model).unwrap();
            assert_sound(&obs);
            // Behind an opaque sheet: 20 log10(tau) = -180 dB relative to the open view.
            assert!(obs.z[1].power_db < obs.z[0].power_db - 100.0);
        }
    }
    // Shares that are not shares are refused, not clamped.
    assert!(matches!(
        Material::from_rho_alpha(0.6, 0.5),
        Err(ModelError::InvalidMaterial { .. })
    ));
    assert!(matches!(
        Material::from_rho_alpha(-0.1, 0.5),
        Err(ModelError::InvalidMaterial { .. })
    ));
    assert!(matches!(
        Material::from_rho_alpha(f64::NAN, 0.5),
        Err(ModelError::NonFinite { .. })
    ));
}

#[test]
fn ranges_near_zero_and_near_the_maximum_stay_finite() {
    let pose = Pose2::default();
    let m = Material::from_rho_alpha(0.2, 0.1).unwrap();
    for model in forms() {
        for r in [1e-5, 1e-3, 0.1, 199.9, 200.0, 1e4] {
            let obs = observe_beam(
                &pose,
                &[BeamFeature {
                    xy: [r, 0.0],
                    material: m,
                }],
                0.0,
                &model,
            )
            .unwrap();
            assert_sound(&obs);
            // Geometry rows are bounded by 1/R^2 (bearing) as plain range-bearing SLAM is.
            let worst = obs
                .jacobian
                .rows(0, 2)
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(worst <= 1.0f64.max(1.0 / (r * r)) * (1.0 + 1e-12));
        }
    }
    spectrum_is_finite(&[
        SpectrumTarget {
            range_m: 0.0,
            power_db: 30.0,
        },
        SpectrumTarget {
            range_m: 199.9,
            power_db: -60.0,
        },
        SpectrumTarget {
            range_m: 5000.0,
            power_db: -60.0,
        },
        SpectrumTarget {
            range_m: -3.0,
            power_db: -60.0,
        },
    ]);
    // A feature on the sensor has no bearing: a typed error, not a NaN.
    let on_sensor = [BeamFeature {
        xy: [0.0, 0.0],
        material: m,
    }];
    assert!(matches!(
        observe_beam(&pose, &on_sensor, 0.0, &PowerModel::default()),
        Err(ModelError::FeatureAtSensor { .. })
    ));
}

#[test]
fn twenty_targets_in_one_beam_neither_overflow_nor_underflow() {
    let pose = Pose2::new(5.0, -3.0, 1.0);
    let beam = Beam::new(0.3, 0.5, 200.0);
    // 20 features 0.1 m to 9 m apart, alternating light and heavy materials.
    let mut xys = Vec::new();
    let mut materials = Vec::new();
    let mut r = 4.0;
    for i in 0..20 {
        r += if i % 3 == 0 { 0.1 } else { 9.0 };
        xys.push(pose.point_at(r, 0.3 + 0.01 * ((i as f64).sin())));
        materials.push(if i % 2 == 0 {
            Material::from_rho_alpha(0.05, 0.05).unwrap()
        } else {
            Material::from_rho_alpha(0.6, 0.35).unwrap()
        });
    }
    let mut hits = Vec::new();
    features_in_beam(&pose, &beam, xys.iter().copied(), &mut hits);
    assert_eq!(hits.len(), 20);
    assert!(hits.windows(2).all(|w| w[0].range_m <= w[1].range_m));
    let feats: Vec<BeamFeature> = hits
        .iter()
        .map(|h| BeamFeature {
            xy: xys[h.index],
            material: materials[h.index],
        })
        .collect();
    for model in forms() {
        let obs = observe_beam(&pose, &feats, 0.0, &model).unwrap();
        assert_sound(&obs);
        let targets: Vec<PowerTarget> = hits
            .iter()
            .map(|h| PowerTarget {
                range_m: h.range_m,
                material: materials[h.index],
            })
            .collect();
        let mut st = Vec::new();
        beam_spectrum_targets(&model, &targets, 0.0, &mut st).unwrap();
        spectrum_is_finite(&st);
        let bp = beam_powers_with_jacobian(&model, &targets, 0.0).unwrap();
        assert!(bp.power_db.iter().all(|p| p.is_finite()));
        // Textbook: each target behind only loses; the last is far below the first.
        if model.form == SpreadingForm::Textbook {
            assert!(bp.power_db[19] < bp.power_db[0] - 100.0);
        }
    }
}

#[test]
fn extreme_loss_keeps_powers_and_spectra_finite_and_wire_values_clamped() {
    let pose = Pose2::default();
    let m = Material::from_rho_alpha(0.4, 0.1).unwrap();
    let feats = [
        BeamFeature {
            xy: [12.0, 0.0],
            material: m,
        },
        BeamFeature {
            xy: [40.0, 0.0],
            material: m,
        },
    ];
    for loss in [-1e6, -300.0, 300.0, 1e6] {
        for model in forms() {
            let obs = observe_beam(&pose, &feats, loss, &model).unwrap();
            assert_sound(&obs);
            let st: Vec<SpectrumTarget> = obs
                .z
                .iter()
                .map(|z| SpectrumTarget {
                    range_m: z.range_m,
                    power_db: z.power_db,
                })
                .collect();
            spectrum_is_finite(&st);
            let wire = protocol::db_to_bin8(obs.z[0].power_db + 86.0);
            assert_eq!(wire, if loss < 0.0 { 255 } else { 0 });
        }
    }
    for bad in [f64::NAN, f64::INFINITY] {
        assert!(matches!(
            observe_beam(&pose, &feats, bad, &PowerModel::default()),
            Err(ModelError::NonFinite { .. })
        ));
    }
}

#[test]
fn non_finite_inputs_are_typed_errors_everywhere() {
    let pose = Pose2::new(f64::NAN, 0.0, 0.0);
    let m = Material::default();
    let feats = [BeamFeature {
        xy: [1.0, 2.0],
        material: m,
    }];
    assert!(observe_beam(&pose, &feats, 0.0, &PowerModel::default()).is_err());
    let bad_material = [BeamFeature {
        xy: [1.0, 2.0],
        material: Material::new(f64::INFINITY, 0.0),
    }];
    assert!(observe_beam(
        &Pose2::default(),
        &bad_material,
        0.0,
        &PowerModel::default()
    )
    .is_err());
    let geometry = SpectrumGeometry::paper_unit();
    let model =
        SpectrumModel::new(geometry, &Compensation::default(), NoiseModel::default()).unwrap();
    let mut out = vec![0.0; geometry.bins];
    let nan = [SpectrumTarget {
        range_m: f64::NAN,
        power_db: 0.0,
    }];
    assert!(model.predict_into(&nan, &mut out).is_err());
    let mut short = vec![0.0; 3];
    assert!(matches!(
        model.predict_into(&[], &mut short),
        Err(ModelError::BufferTooSmall { .. })
    ));
    let unsorted = [
        PowerTarget {
            range_m: 5.0,
            material: m,
        },
        PowerTarget {
            range_m: 4.0,
            material: m,
        },
    ];
    assert!(matches!(
        beam_powers_with_jacobian(&PowerModel::default(), &unsorted, 0.0),
        Err(ModelError::TargetsNotSorted { index: 1 })
    ));
}
