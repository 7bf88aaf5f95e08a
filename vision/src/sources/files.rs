//! Masks and poses from files ([`FileSequence`]) and from a session's
//! `/vision/mask` and `/vision/pose` channels ([`SessionMeasurements`]).

use std::collections::VecDeque;
use std::iter::Peekable;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use slidetrack_core::TimeNs;
use slidetrack_estimators::roft::Mask;
use slidetrack_session::{ChannelMessage, MessageReader, RawMessage, ReadOptions, VisionMask, VisionPose};

use super::source::{Arrivals, Delayed, FrameTruth, MeasurementSource};
use crate::VisionError;

/// Masks and poses listed in a directory:
///
/// - `masks.csv`: `frame_time_ns,arrival_time_ns,file` per line, `file` a
///   PNG (8-bit, non-zero on the object) relative to the directory;
/// - `poses.csv`: `frame_time_ns,arrival_time_ns,x,y,z,qx,qy,qz,qw` per line
///   (`camera_from_object`, m).
///
/// Either file may be absent. Lines starting with `#` and a header line are
/// skipped. Masks are read when they arrive.
pub struct FileSequence {
    dir: PathBuf,
    masks: VecDeque<(TimeNs, TimeNs, PathBuf)>,
    poses: VecDeque<Delayed<Isometry3<f64>>>,
}

impl FileSequence {
    /// Reads the index files of `dir`; fails when neither exists or a line is malformed.
    pub fn open(dir: &Path) -> Result<FileSequence, VisionError> {
        let masks_csv = dir.join("masks.csv");
        let poses_csv = dir.join("poses.csv");
        if !masks_csv.exists() && !poses_csv.exists() {
            return Err(VisionError::BadFile {
                path: dir.to_path_buf(),
                detail: "no masks.csv or poses.csv: nothing to read masks or poses from".into(),
            });
        }
        let mut masks = Vec::new();
        for (line, fields) in csv_lines(&masks_csv)? {
            let [frame, arrival, file] = &fields[..] else {
                return Err(bad_line(&masks_csv, line, "expected frame_time_ns,arrival_time_ns,file"));
            };
            let (frame, arrival) = (time(frame, &masks_csv, line)?, time(arrival, &masks_csv, line)?);
            masks.push((frame, arrival.max(frame), dir.join(file)));
        }
        let mut poses = Vec::new();
        for (line, fields) in csv_lines(&poses_csv)? {
            if fields.len() != 9 {
                return Err(bad_line(
                    &poses_csv,
                    line,
                    "expected frame_time_ns,arrival_time_ns,x,y,z,qx,qy,qz,qw",
                ));
            }
            let (frame, arrival) = (time(&fields[0], &poses_csv, line)?, time(&fields[1], &poses_csv, line)?);
            let v: Vec<f64> = fields[2..]
                .iter()
                .map(|s| s.parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| bad_line(&poses_csv, line, &e.to_string()))?;
            let q = Quaternion::new(v[6], v[3], v[4], v[5]);
            if !v.iter().all(|x| x.is_finite()) || q.norm() < 1e-9 {
                return Err(bad_line(&poses_csv, line, "the pose is not finite or its quaternion is zero"));
            }
            let pose =
                Isometry3::from_parts(Translation3::new(v[0], v[1], v[2]), UnitQuaternion::new_normalize(q));
            poses.push(Delayed { frame_t: frame, arrival_t: arrival.max(frame), value: pose });
        }
        masks.sort_by_key(|m| m.1);
        poses.sort_by_key(|p| p.arrival_t);
        Ok(FileSequence { dir: dir.to_path_buf(), masks: masks.into(), poses: poses.into() })
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl MeasurementSource for FileSequence {
    fn on_frame(&mut self, t: TimeNs, _truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        let mut out = Arrivals::default();
        while self.masks.front().is_some_and(|m| m.1 <= t) {
            if let Some((frame_t, arrival_t, path)) = self.masks.pop_front() {
                out.masks.push(Delayed { frame_t, arrival_t, value: read_mask(&path)? });
            }
        }
        while self.poses.front().is_some_and(|p| p.arrival_t <= t) {
            out.poses.extend(self.poses.pop_front());
        }
        Ok(out)
    }
}

/// An 8-bit PNG mask, non-zero on the object.
pub fn read_mask(path: &Path) -> Result<Mask, VisionError> {
    let gray = crate::input::codec::decode_file(path, |b| {
        slidetrack_calibration::codec::decode(b, slidetrack_core::PixelFormat::Gray8)
    })?;
    crate::cloud::mask(gray.width, gray.height, &gray.data)
}

fn csv_lines(path: &Path) -> Result<Vec<(usize, Vec<String>)>, VisionError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text =
        std::fs::read_to_string(path).map_err(|source| VisionError::Io { path: path.into(), source })?;
    Ok(text
        .lines()
        .enumerate()
        .filter(|(_, l)| {
            let l = l.trim();
            !l.is_empty() && !l.starts_with('#') && !l.starts_with("frame_time_ns")
        })
        .map(|(n, l)| (n + 1, l.split(',').map(|f| f.trim().to_string()).collect()))
        .collect())
}

fn time(field: &str, path: &Path, line: usize) -> Result<TimeNs, VisionError> {
    field.parse::<u64>().map(TimeNs).map_err(|e| bad_line(path, line, &format!("time '{field}': {e}")))
}

fn bad_line(path: &Path, line: usize, detail: &str) -> VisionError {
    VisionError::BadFile { path: path.into(), detail: format!("line {line}: {detail}") }
}

/// The `/vision/mask` and `/vision/pose` channels of a session: each
/// message's `log_time` is its arrival and its `timestamp` the frame it was
/// computed on. Read lazily, in file order.
pub struct SessionMeasurements {
    path: PathBuf,
    reader: Peekable<MessageReader>,
}

impl SessionMeasurements {
    /// Opens the session; a session without these channels yields nothing.
    pub fn open(path: &Path, options: ReadOptions) -> Result<SessionMeasurements, VisionError> {
        let reader = MessageReader::open(path, &[VisionMask::TOPIC, VisionPose::TOPIC], options)?.peekable();
        Ok(SessionMeasurements { path: path.to_path_buf(), reader })
    }

    fn decode(&self, m: &RawMessage, arrivals: &mut Arrivals) -> Result<(), VisionError> {
        let bad = |detail: String| VisionError::BadSession { path: self.path.clone(), detail };
        if m.topic() == VisionMask::TOPIC {
            let raw: VisionMask =
                serde_json::from_slice(&m.data).map_err(|e| bad(format!("{}: {e}", m.topic())))?;
            let inside =
                raw.0.to_mask().ok_or_else(|| bad("a /vision/mask message is not a mono8 image".into()))?;
            let mask = crate::cloud::mask(raw.0.width, raw.0.height, &inside)?;
            arrivals.masks.push(Delayed {
                frame_t: raw.0.timestamp.into(),
                arrival_t: m.log_time,
                value: mask,
            });
        } else {
            let raw: VisionPose =
                serde_json::from_slice(&m.data).map_err(|e| bad(format!("{}: {e}", m.topic())))?;
            // A non-finite pose is dropped here, as a network's failure.
            if let Some(pose) = raw.0.pose.to_isometry() {
                arrivals.poses.push(Delayed {
                    frame_t: raw.0.timestamp.into(),
                    arrival_t: m.log_time,
                    value: pose,
                });
            }
        }
        Ok(())
    }
}

impl MeasurementSource for SessionMeasurements {
    fn on_frame(&mut self, t: TimeNs, _truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        let mut out = Arrivals::default();
        while let Some(next) = self.reader.peek() {
            match next {
                Ok(m) if m.log_time > t => break,
                Ok(_) => {
                    if let Some(Ok(m)) = self.reader.next() {
                        self.decode(&m, &mut out)?;
                    }
                }
                Err(_) => {
                    if let Some(Err(e)) = self.reader.next() {
                        return Err(e.into());
                    }
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_sequence_delivers_in_arrival_order() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("poses.csv"),
            "frame_time_ns,arrival_time_ns,x,y,z,qx,qy,qz,qw\n100,300,0.1,0,0.5,0,0,0,1\n0,200,0,0,0.5,0,0,0,2\n",
        )
        .unwrap();
        let mut seq = FileSequence::open(dir.path()).unwrap();
        assert!(seq.on_frame(TimeNs(150), None).unwrap().poses.is_empty());
        let a = seq.on_frame(TimeNs(320), None).unwrap();
        assert_eq!(a.poses.iter().map(|p| p.frame_t).collect::<Vec<_>>(), vec![TimeNs(0), TimeNs(100)]);
        assert!((a.poses[0].value.rotation.w - 1.0).abs() < 1e-12, "normalised");
    }

    #[test]
    fn bad_index_files_and_missing_masks_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        assert!(matches!(FileSequence::open(dir.path()), Err(VisionError::BadFile { .. })));
        std::fs::write(dir.path().join("poses.csv"), "0,0,1,2,3\n").unwrap();
        let e = FileSequence::open(dir.path()).err().unwrap().to_string();
        assert!(e.contains("line 1"), "{e}");
        std::fs::write(dir.path().join("poses.csv"), "").unwrap();
        std::fs::write(dir.path().join("masks.csv"), "0,10,missing.png\n").unwrap();
        let mut seq = FileSequence::open(dir.path()).unwrap();
        assert!(matches!(seq.on_frame(TimeNs(20), None), Err(VisionError::Io { .. })));
    }
}
