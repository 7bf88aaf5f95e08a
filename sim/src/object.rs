//! Objects of the simulated rig, described in TOML (`drivers/objects/*.toml`).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::SimError;
use super::camera::ObjectAppearance;
use super::surface::SurfaceConfig;

/// The objects that ship with slidetrack, as `(name, TOML text)`.
pub const BUILTIN_OBJECTS: [(&str, &str); 3] = [
    ("box", include_str!("../objects/box.toml")),
    ("bottle", include_str!("../objects/bottle.toml")),
    ("mustard", include_str!("../objects/mustard.toml")),
];

/// An object that slides in the hand.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectConfig {
    /// Short name (`box`).
    pub name: String,
    /// One line for humans.
    #[serde(default)]
    pub description: String,
    /// Mass (kg).
    pub mass_kg: f64,
    /// Contact friction between the object and the fingertips.
    pub friction: FrictionConfig,
    /// Size of the object.
    pub geometry: ObjectGeometry,
    /// Texture of the surface the fingertips slide on.
    #[serde(default)]
    pub surface: SurfaceConfig,
    /// How the camera sees it.
    #[serde(default)]
    pub appearance: ObjectAppearance,
    /// The controlled-sliding experiment's per-object settings.
    pub experiment: ExperimentSettings,
    /// Per-trial random variation.
    #[serde(default)]
    pub jitter: TrialJitter,
}

/// LuGre friction with normal-force scaling (the "normalised" LuGre model):
/// per fingertip, with bristle deflection `z` (m), relative velocity `v` (m/s)
/// and normal force `F_n` (N),
/// `g(v) = mu_k + (mu_s - mu_k) exp(-(v/v_s)^2)`,
/// `dz/dt = v - sigma0 |v| z / g(v)`,
/// `F = F_n (sigma0 z + sigma1 dz/dt + sigma2 v)`.
/// Static friction gives presliding (elastic bristle deflection before gross
/// sliding) and, with `mu_s > mu_k`, stick-slip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionConfig {
    /// Static friction coefficient `mu_s`.
    pub mu_static: f64,
    /// Kinetic (Coulomb) friction coefficient `mu_k`.
    pub mu_kinetic: f64,
    /// Stribeck velocity `v_s` (m/s).
    pub stribeck_velocity_mps: f64,
    /// Bristle stiffness per newton of normal force, `sigma0` (1/m).
    pub bristle_stiffness_per_m: f64,
    /// Bristle damping per newton of normal force, `sigma1` (s/m).
    pub bristle_damping_s_per_m: f64,
    /// Viscous friction per newton of normal force, `sigma2` (s/m).
    pub viscous_s_per_m: f64,
    /// Optional multiplier of both coefficients against the travel `p` (m):
    /// `[[p_m, factor], ...]`, increasing `p_m`, interpolated linearly.
    #[serde(default)]
    pub profile: Vec<[f64; 2]>,
}

impl FrictionConfig {
    /// The friction multiplier at travel `p_m` (1 without a profile).
    pub fn profile_factor(&self, p_m: f64) -> f64 {
        let pts = &self.profile;
        match pts.len() {
            0 => 1.0,
            1 => pts[0][1],
            _ => {
                if p_m <= pts[0][0] {
                    return pts[0][1];
                }
                for w in pts.windows(2) {
                    let ([p0, f0], [p1, f1]) = (w[0], w[1]);
                    if p_m <= p1 {
                        let s = if p1 > p0 { (p_m - p0) / (p1 - p0) } else { 1.0 };
                        return f0 + s * (f1 - f0);
                    }
                }
                pts[pts.len() - 1][1]
            }
        }
    }
}

/// Dimensions of the object (m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectGeometry {
    /// Extent across the grip, between the thumb and the opposing fingers (m).
    pub width_m: f64,
    /// Extent along the sliding axis (m).
    pub length_m: f64,
    /// Travel along the sliding axis before the fingertips lose the object (m).
    pub slide_range_m: f64,
    /// Extent towards the camera (m).
    pub depth_m: f64,
}

/// Settings of the controlled-sliding experiment for this object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentSettings {
    /// Grasp strength `tau_g,max` at which the object does not move (counts).
    pub grasp_max_counts: f64,
    /// Grasp strength `tau_g,min` at which the object slides noticeably (counts).
    pub grasp_min_counts: f64,
    /// Period of the grasp-strength reference (s).
    pub period_s: f64,
    /// Sharpness of the dips of the reference (1 = cosine; larger = narrower dips).
    #[serde(default = "one")]
    pub sharpness: f64,
    /// Abort when the marker shows the object further than this from its start (m).
    pub travel_limit_m: f64,
}

/// Relative spread of per-trial parameters: each is multiplied by a factor
/// drawn uniformly in `[1 - rel, 1 + rel]` from the trial's seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrialJitter {
    /// Relative spread of the mass.
    pub mass_rel: f64,
    /// Relative spread of the friction coefficients.
    pub friction_rel: f64,
    /// Relative spread of each sensor's gains.
    pub sensor_gain_rel: f64,
}

impl Default for TrialJitter {
    fn default() -> Self {
        TrialJitter { mass_rel: 0.0, friction_rel: 0.0, sensor_gain_rel: 0.0 }
    }
}

fn one() -> f64 {
    1.0
}

impl ObjectConfig {
    /// Parses an object from TOML; `origin` names the source in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<ObjectConfig, SimError> {
        let obj: ObjectConfig = slidetrack_core::parse_toml(text, origin)?;
        obj.validate(origin)?;
        Ok(obj)
    }

    /// A built-in object by name, or an object from a `.toml` file path.
    pub fn load(name_or_path: &str) -> Result<ObjectConfig, SimError> {
        if let Some((_, text)) = BUILTIN_OBJECTS.iter().find(|(n, _)| *n == name_or_path) {
            return ObjectConfig::from_toml(text, &format!("built-in object '{name_or_path}'"));
        }
        let path = Path::new(name_or_path);
        if path.extension().is_some_and(|e| e == "toml") {
            let text = std::fs::read_to_string(path).map_err(|e| SimError::BadConfig {
                origin: path.display().to_string(),
                detail: e.to_string(),
            })?;
            return ObjectConfig::from_toml(&text, &path.display().to_string());
        }
        Err(SimError::UnknownObject {
            name: name_or_path.to_string(),
            known: BUILTIN_OBJECTS.iter().map(|(n, _)| n.to_string()).collect(),
        })
    }

    fn validate(&self, origin: &str) -> Result<(), SimError> {
        let bad = |detail: String| SimError::BadConfig { origin: origin.to_string(), detail };
        let f = &self.friction;
        let positive = [
            ("mass_kg", self.mass_kg),
            ("friction.mu_kinetic", f.mu_kinetic),
            ("friction.stribeck_velocity_mps", f.stribeck_velocity_mps),
            ("friction.bristle_stiffness_per_m", f.bristle_stiffness_per_m),
            ("geometry.width_m", self.geometry.width_m),
            ("geometry.slide_range_m", self.geometry.slide_range_m),
            ("experiment.period_s", self.experiment.period_s),
            ("experiment.sharpness", self.experiment.sharpness),
            ("experiment.travel_limit_m", self.experiment.travel_limit_m),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(format!("{field} must be a positive number, got {v}")));
            }
        }
        if f.mu_static < f.mu_kinetic {
            return Err(bad(format!(
                "friction.mu_static ({}) must not be below friction.mu_kinetic ({})",
                f.mu_static, f.mu_kinetic
            )));
        }
        if f.bristle_damping_s_per_m < 0.0 || f.viscous_s_per_m < 0.0 {
            return Err(bad("friction damping terms must not be negative".into()));
        }
        if f.profile.windows(2).any(|w| w[1][0] <= w[0][0]) || f.profile.iter().any(|p| p[1] <= 0.0) {
            return Err(bad("friction.profile needs increasing positions and positive factors".into()));
        }
        let e = &self.experiment;
        if !(e.grasp_min_counts > 0.0 && e.grasp_max_counts > e.grasp_min_counts) {
            return Err(bad(format!(
                "experiment needs 0 < grasp_min_counts < grasp_max_counts, got {} and {}",
                e.grasp_min_counts, e.grasp_max_counts
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_objects_parse() {
        for (name, _) in BUILTIN_OBJECTS {
            let o = ObjectConfig::load(name).unwrap();
            assert_eq!(o.name, name);
        }
    }

    #[test]
    fn unknown_object_lists_the_known_ones() {
        let e = ObjectConfig::load("teapot").unwrap_err().to_string();
        assert!(e.contains("teapot") && e.contains("box") && e.contains("mustard"), "{e}");
    }

    #[test]
    fn malformed_toml_names_its_origin() {
        let e = ObjectConfig::from_toml("name = \"x\"\nmass_kg = ", "my.toml").unwrap_err().to_string();
        assert!(e.contains("my.toml"), "{e}");
        let text = BUILTIN_OBJECTS[0].1.replace("mass_kg = 0.080", "mass_kg = -1.0");
        let e = ObjectConfig::from_toml(&text, "neg.toml").unwrap_err().to_string();
        assert!(e.contains("mass_kg"), "{e}");
    }

    #[test]
    fn friction_profile_interpolates_and_holds_at_the_ends() {
        let o = ObjectConfig::load("mustard").unwrap();
        let f = &o.friction;
        assert_eq!(f.profile_factor(-1.0), 1.0);
        assert!((f.profile_factor(0.0075) - 0.95).abs() < 1e-12);
        assert_eq!(f.profile_factor(5.0), 1.0);
        assert_eq!(ObjectConfig::load("box").unwrap().friction.profile_factor(0.03), 1.0);
    }
}
