//! Which motion a dEKF tracks: the thesis's sliding along one axis, or
//! planar slip in the contact plane of a parallel gripper.
//!
//! A state of `dofs` degrees of freedom is `x = (p, v)` with `2 dofs`
//! components: the positions first, then their rates. The measurement (the
//! feature network's output) has `dofs` components. The thesis's state
//! (eq. 6.1) is the case `dofs = 1`.

use serde::{Deserialize, Serialize};

/// The state a model tracks (`docs/model-format.md`, metadata `state`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StateKind {
    /// `(p, v)`: position along the sliding axis (cm) and its velocity
    /// (cm/s), thesis eq. 6.1.
    #[default]
    Sliding,
    /// `(x, y, theta, vx, vy, omega)`: the translation of the grip point in
    /// the contact plane along its two axes (mm), the rotation about the
    /// contact normal (deg), and their rates (mm/s, deg/s). Millimetres and
    /// degrees, so that the typical motions of a held object (a few mm, a
    /// few degrees) weigh alike in the loss, a plain sum of squares.
    Planar,
}

impl StateKind {
    /// Every kind, in the order of the documentation.
    pub const ALL: [StateKind; 2] = [StateKind::Sliding, StateKind::Planar];

    /// `sliding` or `planar` (the name in the model file and on the command line).
    pub fn name(self) -> &'static str {
        match self {
            StateKind::Sliding => "sliding",
            StateKind::Planar => "planar",
        }
    }

    /// Degrees of freedom: positions in the state, and components of the measurement.
    pub fn dofs(self) -> usize {
        match self {
            StateKind::Sliding => 1,
            StateKind::Planar => 3,
        }
    }

    /// Components of the state, `2 dofs`.
    pub fn dim(self) -> usize {
        2 * self.dofs()
    }

    /// Names of the state's components, positions then rates.
    pub fn components(self) -> &'static [&'static str] {
        match self {
            StateKind::Sliding => &["p", "v"],
            StateKind::Planar => &["x", "y", "theta", "vx", "vy", "omega"],
        }
    }

    /// Units of the state's components (the model file's `state_units`).
    pub fn units(self) -> Vec<String> {
        let units: &[&str] = match self {
            StateKind::Sliding => &["cm", "cm/s"],
            StateKind::Planar => &["mm", "mm", "deg", "mm/s", "mm/s", "deg/s"],
        };
        units.iter().map(|u| (*u).to_string()).collect()
    }

    /// The initial covariance's diagonal `P0` (thesis Sec. 6.3: 0.1 for
    /// every component, in the state's units squared).
    pub fn default_p0_diag(self) -> Vec<f64> {
        vec![0.1; self.dim()]
    }

    /// Factors from the SI units of a truth sample (m, m/s; rad, rad/s) to
    /// the state's units, per component.
    pub fn from_si(self) -> Vec<f64> {
        const DEG: f64 = 180.0 / std::f64::consts::PI;
        match self {
            StateKind::Sliding => vec![100.0; 2],
            StateKind::Planar => vec![1000.0, 1000.0, DEG, 1000.0, 1000.0, DEG],
        }
    }

    /// True for [`StateKind::Sliding`] (serde: the default is not written,
    /// so a sliding model's file is what it was before planar models existed).
    pub fn is_sliding(&self) -> bool {
        *self == StateKind::Sliding
    }
}

impl std::fmt::Display for StateKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for StateKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        StateKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown state `{s}` (sliding or planar)"))
    }
}
