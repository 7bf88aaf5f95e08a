//! Writing RGB-D frames, masks, poses and estimates to sessions, on the
//! channels of `docs/session-format.md`.

use std::collections::BTreeMap;

use nalgebra::Isometry3;
use slidetrack_core::{CameraIntrinsics, EncodedImage, ObjectTruth as SimObjectTruth, RgbdFrame, TimeNs};
use slidetrack_estimators::orientation::odometry::{OdometryCovariance, twist_in_object};
use slidetrack_estimators::roft::Mask;
use slidetrack_session::odometry::{MaskUkfOdometry, Odometry, RoftOdometry};
use slidetrack_session::vision_pose::{
    MaskUkfPose, MaskUkfTransform, MaskUkfVelocity, RoftPose, RoftTransform, RoftVelocity,
};
use slidetrack_session::{
    ChannelHandle, ChannelMessage, CompressedImage, FrameTransform, Logger, ObjectTruth, PoseInFrame,
    RawImage, RgbdCalibration, RgbdColor, RgbdDepth, RgbdMask, VelocityEstimate, VisionMask, VisionPose,
};

use crate::VisionError;
use crate::online::{TrackedState, TrackerKind};

/// The camera's optical frame name in sessions.
pub const CAMERA_FRAME: &str = "camera";

/// The channels of an RGB-D recording.
pub struct RgbdChannels {
    color: ChannelHandle<RgbdColor>,
    depth: ChannelHandle<RgbdDepth>,
    mask: ChannelHandle<RgbdMask>,
    truth: ChannelHandle<ObjectTruth>,
    vision_mask: ChannelHandle<VisionMask>,
    vision_pose: ChannelHandle<VisionPose>,
}

impl RgbdChannels {
    /// Registers the channels and logs the calibration at time 0.
    pub fn register(logger: &Logger, intrinsics: &CameraIntrinsics) -> Result<RgbdChannels, VisionError> {
        let calibration = logger.register::<RgbdCalibration>(BTreeMap::new())?;
        let message = RgbdCalibration(slidetrack_session::CameraCalibration::new(
            TimeNs::ZERO,
            CAMERA_FRAME,
            intrinsics,
        ));
        logger.log_json(&calibration, TimeNs::ZERO, TimeNs::ZERO, 0, &message)?;
        RgbdChannels::attach(logger)
    }

    /// The channels of a session whose frames and calibration something
    /// else records (the camera shared with the marker): the same
    /// channels, no calibration logged.
    pub fn attach(logger: &Logger) -> Result<RgbdChannels, VisionError> {
        let none = BTreeMap::new;
        Ok(RgbdChannels {
            color: logger.register::<RgbdColor>(none())?,
            depth: logger.register::<RgbdDepth>(none())?,
            mask: logger.register::<RgbdMask>(none())?,
            truth: logger.register::<ObjectTruth>(none())?,
            vision_mask: logger.register::<VisionMask>(none())?,
            vision_pose: logger.register::<VisionPose>(none())?,
        })
    }

    /// Logs a frame (colour compressed as `color_jpeg`), and its truth and
    /// ground-truth mask when given.
    pub fn log_frame(
        &self,
        logger: &Logger,
        frame: &RgbdFrame,
        color_jpeg: &EncodedImage,
        truth: Option<&SimObjectTruth>,
        mask: Option<&Mask>,
    ) -> Result<(), VisionError> {
        let (t, seq) = (frame.t, frame.sequence as u32);
        logger.log_json(
            &self.color,
            t,
            t,
            seq,
            &RgbdColor(CompressedImage::new(t, CAMERA_FRAME, color_jpeg)),
        )?;
        logger.log_json(&self.depth, t, t, seq, &RgbdDepth::new(t, CAMERA_FRAME, &frame.depth)?)?;
        if let Some(m) = mask {
            logger.log_json(
                &self.mask,
                t,
                t,
                seq,
                &RgbdMask(RawImage::mask(t, CAMERA_FRAME, m.width(), m.height(), &m.to_bytes())),
            )?;
        }
        if let Some(truth) = truth {
            logger.log_json(&self.truth, t, t, seq, &ObjectTruth::from(truth))?;
        }
        Ok(())
    }

    /// Logs the colour and depth of one pair without ever blocking (a
    /// camera's own recording beside a trial): each is dropped, and counted
    /// in the session's `images_dropped`, when the writer is behind. Returns
    /// whether both were queued.
    pub fn log_pair_lossy(
        &self,
        logger: &Logger,
        frame: &RgbdFrame,
        color_jpeg: &EncodedImage,
    ) -> Result<bool, VisionError> {
        let (t, seq) = (frame.t, frame.sequence as u32);
        let color = RgbdColor(CompressedImage::new(t, CAMERA_FRAME, color_jpeg));
        let color_queued = logger.log_json_lossy(&self.color, t, t, seq, &color)?;
        let depth = RgbdDepth::new(t, CAMERA_FRAME, &frame.depth)?;
        let depth_queued = logger.log_json_lossy(&self.depth, t, t, seq, &depth)?;
        Ok(color_queued && depth_queued)
    }

    /// Logs a mask of the segmentation source computed on frame `frame_t`,
    /// arriving at `arrival_t`.
    pub fn log_vision_mask(
        &self,
        logger: &Logger,
        frame_t: TimeNs,
        arrival_t: TimeNs,
        mask: &Mask,
    ) -> Result<(), VisionError> {
        let raw = RawImage::mask(frame_t, CAMERA_FRAME, mask.width(), mask.height(), &mask.to_bytes());
        Ok(logger.log_json(&self.vision_mask, arrival_t, frame_t, 0, &VisionMask(raw))?)
    }

    /// Logs a pose of the pose source computed on frame `frame_t`, arriving at `arrival_t`.
    pub fn log_vision_pose(
        &self,
        logger: &Logger,
        frame_t: TimeNs,
        arrival_t: TimeNs,
        pose: &Isometry3<f64>,
    ) -> Result<(), VisionError> {
        let message = VisionPose(PoseInFrame::new(frame_t, CAMERA_FRAME, pose));
        Ok(logger.log_json(&self.vision_pose, arrival_t, frame_t, 0, &message)?)
    }
}

/// The estimate channels of one tracker: `/estimate/pose/<tracker>`,
/// `/estimate/transform/<tracker>`, `/estimate/velocity/<tracker>` and
/// `/estimate/odometry/<tracker>` (the estimate with its covariance).
pub enum EstimateChannels {
    /// MaskUKF's.
    MaskUkf(
        ChannelHandle<MaskUkfPose>,
        ChannelHandle<MaskUkfTransform>,
        ChannelHandle<MaskUkfVelocity>,
        ChannelHandle<MaskUkfOdometry>,
    ),
    /// ROFT's.
    Roft(
        ChannelHandle<RoftPose>,
        ChannelHandle<RoftTransform>,
        ChannelHandle<RoftVelocity>,
        ChannelHandle<RoftOdometry>,
    ),
}

impl EstimateChannels {
    /// Registers the channels of `kind`.
    pub fn register(logger: &Logger, kind: TrackerKind) -> Result<EstimateChannels, VisionError> {
        let none = BTreeMap::new;
        Ok(match kind {
            TrackerKind::MaskUkf => EstimateChannels::MaskUkf(
                logger.register(none())?,
                logger.register(none())?,
                logger.register(none())?,
                logger.register(none())?,
            ),
            TrackerKind::Roft => EstimateChannels::Roft(
                logger.register(none())?,
                logger.register(none())?,
                logger.register(none())?,
                logger.register(none())?,
            ),
        })
    }

    /// The topics, for messages.
    pub fn topics(kind: TrackerKind) -> [&'static str; 4] {
        match kind {
            TrackerKind::MaskUkf => {
                [MaskUkfPose::TOPIC, MaskUkfTransform::TOPIC, MaskUkfVelocity::TOPIC, MaskUkfOdometry::TOPIC]
            }
            TrackerKind::Roft => {
                [RoftPose::TOPIC, RoftTransform::TOPIC, RoftVelocity::TOPIC, RoftOdometry::TOPIC]
            }
        }
    }

    /// Logs one estimate at its frame's time.
    pub fn log(&self, logger: &Logger, state: &TrackedState) -> Result<(), VisionError> {
        let t = state.t;
        let pose = PoseInFrame::new(t, CAMERA_FRAME, &state.estimate.camera_from_object);
        let kind = match self {
            EstimateChannels::MaskUkf(..) => TrackerKind::MaskUkf,
            EstimateChannels::Roft(..) => TrackerKind::Roft,
        };
        let child = format!("object/{}", kind.name());
        let odometry = odometry_message(state, &child);
        let transform = FrameTransform::new(t, CAMERA_FRAME, &child, &state.estimate.camera_from_object);
        let velocity = VelocityEstimate {
            frame_id: CAMERA_FRAME.into(),
            linear_velocity_mps: state.estimate.linear_velocity_mps.into(),
            angular_velocity_radps: state.estimate.angular_velocity_radps.into(),
        };
        match self {
            EstimateChannels::MaskUkf(p, tf, v, o) => {
                logger.log_json(p, t, t, 0, &MaskUkfPose(pose))?;
                logger.log_json(tf, t, t, 0, &MaskUkfTransform(transform))?;
                logger.log_json(v, t, t, 0, &MaskUkfVelocity(velocity))?;
                logger.log_json(o, t, t, 0, &MaskUkfOdometry(odometry))?;
            }
            EstimateChannels::Roft(p, tf, v, o) => {
                logger.log_json(p, t, t, 0, &RoftPose(pose))?;
                logger.log_json(tf, t, t, 0, &RoftTransform(transform))?;
                logger.log_json(v, t, t, 0, &RoftVelocity(velocity))?;
                logger.log_json(o, t, t, 0, &RoftOdometry(odometry))?;
            }
        }
        Ok(())
    }
}

/// The estimate with its covariance as `slidetrack.Odometry`: the pose in
/// the camera frame, the twist in the object frame `child`.
pub fn odometry_message(state: &TrackedState, child: &str) -> Odometry {
    let pose = &state.estimate.camera_from_object;
    let twist = twist_in_object(&state.estimate);
    Odometry {
        frame_id: CAMERA_FRAME.into(),
        child_frame_id: child.into(),
        position_m: pose.translation.vector.into(),
        orientation: (&pose.rotation).into(),
        pose_covariance: OdometryCovariance::row_major(&state.covariance.pose),
        linear_velocity_in_child_mps: [twist[0], twist[1], twist[2]],
        angular_velocity_in_child_radps: [twist[3], twist[4], twist[5]],
        twist_covariance: OdometryCovariance::row_major(&state.covariance.twist_in_child),
    }
}
