//! Feature kinds and their default materials.
//!
//! The paper models every feature by its normalised reflectivity `rho`, its normalised
//! absorption `alpha` and the transmitted share `tau = 1 - rho - alpha`. The defaults below
//! are the simulator's choices, not measurements: they follow the paper's qualitative
//! statement (section I, footnote 1, after its figure 1) that at 77 GHz wood, plastic and
//! foliage attenuate little while brick and concrete attenuate a lot, and make metal
//! (lamp posts, the corner reflector) opaque. A scene may override both values per feature.

use serde::Deserialize;

/// What a feature is. Decides its default `(rho, alpha)` and is written to the ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FeatureKind {
    /// A tree trunk with foliage: partly transparent, lossy.
    Tree,
    /// A metal lamp post: a strong, opaque, small-section return.
    LampPost,
    /// Wooden boards (a fence or the paper's 0.8 cm wooden sheet): mostly transparent.
    WoodenFence,
    /// A perspex (acrylic) sheet: weakly reflecting, mostly transparent.
    PerspexSheet,
    /// A corner reflector such as the paper's 177 m^2 one: nearly all power reflected.
    Reflector,
    /// Brick or concrete (walls, steps): reflecting and absorbing, nothing passes.
    Wall,
}

impl FeatureKind {
    /// Every kind, in declaration order.
    pub const ALL: [FeatureKind; 6] = [
        FeatureKind::Tree,
        FeatureKind::LampPost,
        FeatureKind::WoodenFence,
        FeatureKind::PerspexSheet,
        FeatureKind::Reflector,
        FeatureKind::Wall,
    ];

    /// The name used in scene files and in the ground truth.
    pub fn name(self) -> &'static str {
        match self {
            FeatureKind::Tree => "tree",
            FeatureKind::LampPost => "lamp-post",
            FeatureKind::WoodenFence => "wooden-fence",
            FeatureKind::PerspexSheet => "perspex-sheet",
            FeatureKind::Reflector => "reflector",
            FeatureKind::Wall => "wall",
        }
    }

    /// Default `(rho, alpha)`; `tau = 1 - rho - alpha`.
    ///
    /// radar-model calibrates eq. 13 with an illuminated area `A_I = 200 m^2`, so `rho A_I` is
    /// a feature's radar cross section: the paper's 177 m^2 reflector is `rho = 0.885`.
    ///
    /// | kind | rho | RCS | alpha | tau |
    /// |---|---|---|---|---|
    /// | tree | 0.02 | 4 m^2 | 0.60 | 0.38 |
    /// | lamp post | 0.05 | 10 m^2 | 0.95 | 0 |
    /// | wooden fence | 0.02 | 4 m^2 | 0.10 | 0.88 |
    /// | perspex sheet | 0.01 | 2 m^2 | 0.03 | 0.96 |
    /// | reflector | 0.885 | 177 m^2 | 0.115 | 0 |
    /// | wall (per point) | 0.30 | 60 m^2 | 0.70 | 0 |
    ///
    /// "Opaque" kinds keep a tiny transmitted share (1e-6) so the softmax parameterisation the
    /// filter uses (`tau > 0` strictly) can represent them.
    pub fn default_material(self) -> (f64, f64) {
        const OPAQUE_TAU: f64 = 1e-6;
        match self {
            FeatureKind::Tree => (0.02, 0.60),
            FeatureKind::LampPost => (0.05, 0.95 - OPAQUE_TAU),
            FeatureKind::WoodenFence => (0.02, 0.10),
            FeatureKind::PerspexSheet => (0.01, 0.03),
            FeatureKind::Reflector => (0.885, 0.115 - OPAQUE_TAU),
            FeatureKind::Wall => (0.30, 0.70 - OPAQUE_TAU),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_default_material_is_a_valid_partition_of_the_incident_power() {
        for kind in FeatureKind::ALL {
            let (rho, alpha) = kind.default_material();
            let tau = 1.0 - rho - alpha;
            assert!(rho > 0.0 && alpha > 0.0 && tau > 0.0, "{kind:?}");
            assert!(rho < 1.0 && alpha < 1.0 && tau < 1.0, "{kind:?}");
        }
    }

    #[test]
    fn kind_names_round_trip_through_toml() {
        #[derive(Deserialize)]
        struct K {
            k: FeatureKind,
        }
        for kind in FeatureKind::ALL {
            let text = format!("k = \"{}\"", kind.name());
            let parsed: K = toml::from_str(&text).expect("kind parses");
            assert_eq!(parsed.k, kind);
        }
    }
}
