//! The scenes shipped in `sim-sensor/scenes/`, embedded so the binary runs with no files on
//! disk.

use super::Scene;
use crate::error::SceneError;

/// Names of the shipped scenes.
pub const NAMES: [&str; 8] = [
    "penetration-wood",
    "penetration-perspex",
    "outdoor-field",
    "dense-clutter",
    "long-loop",
    "urban-street",
    "city-drive",
    "repeated-blocks",
];

/// The TOML text of a shipped scene.
pub fn text(name: &str) -> Option<&'static str> {
    match name {
        "penetration-wood" => Some(include_str!("../../scenes/penetration-wood.toml")),
        "penetration-perspex" => Some(include_str!("../../scenes/penetration-perspex.toml")),
        "outdoor-field" => Some(include_str!("../../scenes/outdoor-field.toml")),
        "dense-clutter" => Some(include_str!("../../scenes/dense-clutter.toml")),
        "long-loop" => Some(include_str!("../../scenes/long-loop.toml")),
        "urban-street" => Some(include_str!("../../scenes/urban-street.toml")),
        "city-drive" => Some(include_str!("../../scenes/city-drive.toml")),
        "repeated-blocks" => Some(include_str!("../../scenes/repeated-blocks.toml")),
        _ => None,
    }
}

/// Parses a shipped scene.
pub fn load(name: &str) -> Result<Scene, SceneError> {
    let text = text(name).ok_or_else(|| SceneError::UnknownShipped {
        name: name.to_string(),
        shipped: NAMES.join(", "),
    })?;
    Scene::from_toml_str(name, text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::FeatureKind;

    #[test]
    fn every_shipped_scene_parses_and_validates() {
        for name in NAMES {
            let scene = load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(scene.name, name);
            assert!(!scene.features.is_empty(), "{name}");
        }
    }

    #[test]
    fn the_penetration_scene_is_the_papers_geometry() {
        let scene = load("penetration-wood").expect("valid");
        let sheet = &scene.features[0];
        let reflector = &scene.features[1];
        assert_eq!(sheet.kind, FeatureKind::WoodenFence);
        assert_eq!((sheet.x_m, sheet.y_m), (8.5, 0.0));
        assert_eq!(reflector.kind, FeatureKind::Reflector);
        assert_eq!((reflector.x_m, reflector.y_m), (14.0, 0.0));
    }

    #[test]
    fn the_outdoor_field_has_a_paper_sized_feature_count() {
        let scene = load("outdoor-field").expect("valid");
        assert!(
            (30..=65).contains(&scene.features.len()),
            "{}",
            scene.features.len()
        );
    }

    /// Azimuths of the first rotation whose beam holds at least two features, and the most
    /// features any one beam holds (noise off, so exact geometry).
    fn multi_target_beams(name: &str) -> (usize, usize) {
        let mut scene = load(name).expect("valid");
        scene.noise.enabled = false;
        let renderer = std::sync::Arc::new(
            crate::render::SceneRenderer::new(&scene, None, 10.0).expect("renderer"),
        );
        let mut cursor = renderer.cursor();
        let counts: Vec<usize> = (0..u64::from(scene.radar.azimuths))
            .map(|k| cursor.features_in_beam(k).expect("beam").len())
            .collect();
        (
            counts.iter().filter(|&&n| n >= 2).count(),
            counts.into_iter().max().unwrap_or(0),
        )
    }

    #[test]
    fn the_outdoor_field_has_several_targets_down_some_beams() {
        let (beams, most) = multi_target_beams("outdoor-field");
        println!("outdoor-field: {beams} of 200 beams hold 2+ features, at most {most}");
        assert!(beams >= 10, "{beams} beams with two or more targets");
        assert!(most >= 3, "at most {most} targets in one beam");
    }

    #[test]
    fn the_dense_clutter_has_more_multi_target_beams_than_the_field() {
        let (dense, _) = multi_target_beams("dense-clutter");
        let (field, _) = multi_target_beams("outdoor-field");
        println!("dense-clutter: {dense} of 200 beams hold 2+ features (field: {field})");
        assert!(dense > field, "dense {dense} vs field {field}");
    }

    #[test]
    fn an_unknown_shipped_name_lists_the_shipped_ones() {
        let err = load("nowhere").expect_err("unknown");
        assert!(err.to_string().contains("outdoor-field"), "{err}");
    }
}
