//! The two protocols of `slidetrack study`: how sessions are labelled and
//! how models are trained. [`Protocol::Thesis`] is thesis Sec. 6.2.3-6.2.4
//! as written; [`Protocol::Default`] is this project's, with the deviations
//! listed (and measured) in `docs/dekf-study.md`.

use slidetrack_calibration::ground_truth::{default_params, thesis_params};
use slidetrack_calibration::label::GroundTruthSlot;
use slidetrack_estimators::constant_velocity::CvParams;

use crate::dataset::TruthSource;
use slidetrack_estimators::derivative::DEFAULT_OUTLIER_GATE_SIGMA;

use crate::dekf_train::{DEFAULT_POSITION_SHIFT_CM, TrainSpec};

/// A labelling and training protocol.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// This project's: the smoother's defaults with the 5-sigma gate on
    /// `/ground_truth/sliding`; windows shifted along the axis by up to
    /// +-20 cm; the best epoch of the second half of the schedule kept;
    /// isolated tactile spikes gated in the derivative filter.
    #[default]
    Default,
    /// The thesis's: the smoother with `Q = diag(0.01, 0.01)` per 1/30 s
    /// step and `R = 10` (cm), no gate, on `/ground_truth/thesis/sliding`;
    /// the recorded windows; the last epoch kept; every tactile sample
    /// taken. (Inputs are still normalised and gradients clipped: the
    /// thesis is silent on both; `docs/dekf-study.md` measures them.)
    Thesis,
}

impl Protocol {
    /// `default` or `thesis`.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Default => "default",
            Protocol::Thesis => "thesis",
        }
    }

    /// The smoother's parameters of the ground truth.
    pub fn label_params(self) -> CvParams {
        match self {
            Protocol::Default => default_params(),
            Protocol::Thesis => thesis_params(),
        }
    }

    /// Where the ground truth is written: each protocol its own channels,
    /// so that labelling for one never replaces the other's.
    pub fn slot(self) -> GroundTruthSlot {
        match self {
            Protocol::Default => GroundTruthSlot::Default,
            Protocol::Thesis => GroundTruthSlot::Thesis,
        }
    }

    /// The protocol whose labelling writes `truth`, if `slidetrack label` does.
    pub fn labelling(truth: TruthSource) -> Option<Protocol> {
        match truth {
            TruthSource::GroundTruth | TruthSource::Planar => Some(Protocol::Default),
            TruthSource::ThesisGroundTruth => Some(Protocol::Thesis),
            TruthSource::Sim => None,
        }
    }

    /// The ground truth trained and scored against.
    pub fn truth(self) -> TruthSource {
        match self {
            Protocol::Default => TruthSource::GroundTruth,
            Protocol::Thesis => TruthSource::ThesisGroundTruth,
        }
    }

    /// `spec` with this protocol's training: the position shift, the epoch
    /// selection and the spike gate of the default protocol, or none of them.
    pub fn training(self, spec: TrainSpec) -> TrainSpec {
        match self {
            Protocol::Default => TrainSpec {
                position_shift_cm: DEFAULT_POSITION_SHIFT_CM,
                select_epoch: true,
                outlier_gate_sigma: DEFAULT_OUTLIER_GATE_SIGMA,
                ..spec
            },
            Protocol::Thesis => {
                TrainSpec { position_shift_cm: 0.0, select_epoch: false, outlier_gate_sigma: 0.0, ..spec }
            }
        }
    }
}
