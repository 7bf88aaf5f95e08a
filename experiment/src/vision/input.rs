//! The input of a tracking run (a session or a YCB-Video-style directory),
//! its measurement source, the object model and the starting pose.

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::Isometry3;
use slidetrack_core::CameraIntrinsics;
use slidetrack_estimators::metrics::perturbed_start;
use slidetrack_session::{ReadOptions, SessionInfo};
use slidetrack_sim::rgbd::SimObjectKind;
use slidetrack_vision::input::{RgbdSample, RgbdSource, SessionRgbd, YCB_CLASSES, YcbDirectory};
use slidetrack_vision::sources::{
    ArucoConfig, ArucoSource, ExternalConfig, ExternalSource, FileSequence, MeasurementSource,
    SessionMeasurements, SlowNetwork, SlowNetworkConfig, TruthSource,
};
use slidetrack_vision::{ObjectModel, PoseReset, TrackerKind, VisionError};

use super::{Measurements, TrackerStart};

/// Everything a tracking run needs.
pub struct Prepared {
    /// The frames.
    pub source: Box<dyn RgbdSource>,
    /// Masks and poses.
    pub measurements: Box<dyn MeasurementSource>,
    /// The object model.
    pub model: ObjectModel,
    /// The intrinsics of the frames.
    pub intrinsics: CameraIntrinsics,
    /// Where the tracker starts, if not from a measurement.
    pub initial_pose: Option<Isometry3<f64>>,
}

/// Options of an input.
#[derive(Clone)]
pub struct InputOptions<'a> {
    /// The object model: a file, a simulated object's name, or `sim` for the
    /// object of a simulated session.
    pub model: &'a str,
    /// Scale of the model's coordinates to metres (0.001 for millimetres).
    pub model_scale: f64,
    /// The YCB-Video class of a directory: its name or 1-based index.
    pub object: Option<&'a str>,
    /// Where masks and poses come from.
    pub measurements: Measurements,
    /// How the tracker starts.
    pub init: TrackerStart,
    /// Read a truncated session up to its last complete chunk.
    pub recover: bool,
    /// The marker configuration of `--measurements aruco`.
    pub aruco_config: Option<&'a Path>,
    /// The socket of `--measurements external`.
    pub external: Option<ExternalConfig>,
}

/// Opens `input` (a session or a YCB-Video-style directory).
pub fn prepare(input: &Path, o: &InputOptions<'_>) -> Result<Prepared> {
    let options = ReadOptions { recover: o.recover };
    let (source, model, input_measurements): (Box<dyn RgbdSource>, ObjectModel, Box<dyn MeasurementSource>) =
        if input.is_dir() {
            let model = load_model(o.model, o.model_scale, None)?;
            let class = ycb_class(o.object, o.model)?;
            let dir = YcbDirectory::open(input, class, None)?;
            let has_files = input.join("masks.csv").exists() || input.join("poses.csv").exists();
            let measurements: Box<dyn MeasurementSource> = if has_files {
                Box::new(FileSequence::open(input)?)
            } else {
                Box::new(TruthSource { masks: true, poses: false })
            };
            (Box::new(dir), model, measurements)
        } else if input.is_file() {
            let model = load_model(o.model, o.model_scale, Some((input, options)))?;
            let source = SessionRgbd::open(input, options)?;
            let measurements = Box::new(SessionMeasurements::open(input, options)?);
            (Box::new(source), model, measurements)
        } else {
            bail!("{}: no such session file or directory", input.display());
        };
    let intrinsics = source.intrinsics().clone();
    let measurements: Box<dyn MeasurementSource> = match o.measurements {
        Measurements::Input => input_measurements,
        Measurements::Network => Box::new(SlowNetwork::new(SlowNetworkConfig::default())),
        Measurements::Truth => Box::new(TruthSource { masks: true, poses: true }),
        Measurements::Aruco | Measurements::External => own_measurements(o, &model, &intrinsics)?,
    };
    let mut source = Peeked::new(source);
    let initial_pose = match o.init {
        TrackerStart::Measurement => None,
        TrackerStart::Truth | TrackerStart::Perturbed => {
            let first = source.peek()?.and_then(|s| s.truth.map(|t| t.camera_from_object));
            let truth = first.with_context(|| {
                format!("{}: the first frame has no true pose for --init", input.display())
            })?;
            Some(if o.init == TrackerStart::Perturbed { perturbed_start(&truth) } else { truth })
        }
    };
    Ok(Prepared { source: Box::new(source), measurements, model, intrinsics, initial_pose })
}

/// The sources that see the frames themselves: `--measurements aruco`
/// (a marker on the object) and `external` (another process); an error for
/// the others, which come with an input.
pub fn own_measurements(
    o: &InputOptions<'_>,
    model: &ObjectModel,
    intrinsics: &CameraIntrinsics,
) -> Result<Box<dyn MeasurementSource>> {
    Ok(match o.measurements {
        Measurements::Aruco => {
            let path = o.aruco_config.context("--measurements aruco needs --aruco-config FILE")?;
            let config = ArucoConfig::load(path)?;
            let source = ArucoSource::new(config, model, intrinsics)
                .with_context(|| format!("{}: unusable ArUco configuration", path.display()))?;
            Box::new(source)
        }
        Measurements::External => {
            let config = o.external.clone().context("--measurements external needs --listen ADDR")?;
            let source = ExternalSource::listen(config, intrinsics)?;
            eprintln!("external source: listening on {}", source.local_addr());
            Box::new(source)
        }
        other => bail!("--measurements {other:?} comes with an input, not from the frames"),
    })
}

/// `--pose-reset` is MaskUKF's: refused with another tracker.
pub fn check_pose_reset(reset: Option<PoseReset>, kind: TrackerKind) -> Result<()> {
    if reset.is_some() && kind != TrackerKind::MaskUkf {
        bail!("--pose-reset is MaskUKF's: ROFT corrects with every pose it is given");
    }
    Ok(())
}

/// The model: a file, or `sim` for the object of a simulated session.
pub fn load_model(spec: &str, scale: f64, session: Option<(&Path, ReadOptions)>) -> Result<ObjectModel> {
    if spec == "sim" {
        let (path, options) = session.context("--model sim needs a simulated session as --input")?;
        let info = SessionInfo::read(path, options)?;
        let object = info.session_metadata().map(|m| m.object).unwrap_or_default();
        let kind = SimObjectKind::from_name(&object).with_context(|| {
            format!(
                "{}: not a simulated RGB-D session (object '{object}'); give --model FILE",
                path.display()
            )
        })?;
        return Ok(ObjectModel::from_mesh(kind.name(), kind.mesh()));
    }
    if let Some(kind) = SimObjectKind::from_name(spec) {
        return Ok(ObjectModel::from_mesh(kind.name(), kind.mesh()));
    }
    Ok(ObjectModel::load(Path::new(spec), scale)?)
}

/// The YCB class index from `--object` or the model's directory name.
fn ycb_class(object: Option<&str>, model: &str) -> Result<u32> {
    let name = match object {
        Some(o) => o.to_string(),
        None => Path::new(model)
            .parent()
            .and_then(|p| p.file_name())
            .and_then(|n| n.to_str())
            .map(str::to_string)
            .context("give the YCB-Video class with --object (name like 009_gelatin_box, or its index)")?,
    };
    if let Ok(i) = name.parse::<u32>()
        && (1..=YCB_CLASSES.len() as u32).contains(&i)
    {
        return Ok(i);
    }
    YCB_CLASSES.iter().position(|c| *c == name).map(|i| i as u32 + 1).with_context(|| {
        format!("'{name}' is not a YCB-Video class (use --object, e.g. 009_gelatin_box or 8)")
    })
}

/// A source whose first frame can be looked at before tracking.
struct Peeked {
    inner: Box<dyn RgbdSource>,
    first: Option<Option<RgbdSample>>,
}

impl Peeked {
    fn new(inner: Box<dyn RgbdSource>) -> Peeked {
        Peeked { inner, first: None }
    }

    fn peek(&mut self) -> Result<Option<&RgbdSample>> {
        if self.first.is_none() {
            self.first = Some(self.inner.next_frame()?);
        }
        Ok(self.first.as_ref().and_then(Option::as_ref))
    }
}

impl RgbdSource for Peeked {
    fn intrinsics(&self) -> &CameraIntrinsics {
        self.inner.intrinsics()
    }

    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        match self.first.take() {
            Some(first) => Ok(first),
            None => self.inner.next_frame(),
        }
    }

    fn len_hint(&self) -> Option<usize> {
        self.inner.len_hint()
    }
}
