//! Everything written by the recorder reads back identical.

use std::collections::BTreeMap;

use super::*;

fn recorded(name: &str, n: u64) -> (TestDir, PathBuf, EveryChannel, RecorderStats) {
    let dir = TestDir::new(name);
    let path = dir.file("session.mcap");
    let e = EveryChannel::new(n);
    let stats = record_every_channel(&path, &e, RecorderOptions::default());
    (dir, path, e, stats)
}

#[test]
fn every_channel_round_trips_through_recorder_and_reader() {
    let (_dir, path, e, stats) = recorded("roundtrip", 200);
    let o = ReadOptions::default();
    assert_eq!(read_channel::<TactileRaw>(&path, o).unwrap(), e.raw);
    assert_eq!(read_channel::<TactileTare>(&path, o).unwrap(), e.tare);
    assert_eq!(read_channel::<TactileZeroed>(&path, o).unwrap(), e.zeroed);
    assert_eq!(read_channel::<GraspControl>(&path, o).unwrap(), e.grasp);
    assert_eq!(read_channel::<HandCommand>(&path, o).unwrap(), e.hand);
    assert_eq!(read_channel::<CompressedImage>(&path, o).unwrap(), e.image);
    assert_eq!(read_channel::<CameraCalibration>(&path, o).unwrap(), e.calibration);
    assert_eq!(read_channel::<ArucoDetection>(&path, o).unwrap(), e.aruco);
    assert_eq!(read_channel::<SimTruth>(&path, o).unwrap(), e.truth);
    assert_eq!(read_channel::<ProtocolEvent>(&path, o).unwrap(), e.events);

    assert_eq!(stats, RecorderStats { messages_written: e.message_count(), images_dropped: 0 });
    let last = e.events.last().unwrap().0;
    assert_eq!(read_channel::<RecorderStats>(&path, o).unwrap(), vec![(last, stats)]);
}

#[test]
fn message_reader_filters_topics_and_keeps_times_and_sequences() {
    let (_dir, path, e, _) = recorded("filter", 50);
    let topics = [TactileRaw::TOPIC, HandCommand::TOPIC];
    let messages: Vec<RawMessage> =
        MessageReader::open(&path, &topics, ReadOptions::default()).unwrap().map(Result::unwrap).collect();
    assert_eq!(messages.len(), e.raw.len() + e.hand.len());
    let raws: Vec<&RawMessage> = messages.iter().filter(|m| m.topic() == TactileRaw::TOPIC).collect();
    for (i, m) in raws.iter().enumerate() {
        assert_eq!(m.log_time, e.raw[i].0);
        assert_eq!(m.publish_time, e.raw[i].0);
        assert_eq!(m.sequence, i as u32);
        assert_eq!(m.channel.schema_name, "slidetrack.TactileRaw");
        assert_eq!(m.channel.message_encoding, "json");
        assert_eq!(m.channel.schema_encoding, "jsonschema");
        let decoded: TactileRaw = serde_json::from_slice(&m.data).unwrap();
        assert_eq!(decoded, e.raw[i].1);
    }
    let every: usize = MessageReader::open(&path, &[], ReadOptions::default()).unwrap().count();
    assert_eq!(every as u64, e.message_count() + 1, "every topic, plus /recorder/stats");
}

#[test]
fn session_info_from_the_summary_matches_a_full_scan() {
    let (_dir, path, e, _) = recorded("info", 300);
    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    let (file, size) = crate::scan::open_session(&path).unwrap();
    let scanned = crate::summary::scan_info(&path, file, size, true, ReadOptions::default()).unwrap();
    assert_eq!(info, scanned);

    assert!(!info.truncated);
    assert!(info.chunk_count >= 1);
    assert_eq!(info.message_count, e.message_count() + 1);
    assert_eq!(info.start, Some(TimeNs::ZERO));
    assert_eq!(info.end, Some(t_ms(300)));
    assert_eq!(info.duration, std::time::Duration::from_millis(300));
    let raw = info.channel(TactileRaw::TOPIC).unwrap();
    assert_eq!(raw.schema_name, TactileRaw::SCHEMA_NAME);
    assert_eq!(raw.message_count, 300);
    assert_eq!(raw.first_log_time, Some(TimeNs::ZERO));
    assert_eq!(raw.last_log_time, Some(t_ms(299)));
    assert!((raw.mean_rate_hz.unwrap() - 1000.0).abs() < 1e-9);
    assert_eq!(info.channel(CameraCalibration::TOPIC).unwrap().mean_rate_hz, None);
    let topics: Vec<&str> = info.channels.iter().map(|c| c.topic.as_str()).collect();
    assert_eq!(topics.len(), 11);
    assert!(topics.contains(&RecorderStats::TOPIC));

    assert_eq!(info.session_metadata(), Some(session_metadata()));
    let outcome = info.outcome().unwrap();
    assert_eq!(outcome, SessionOutcome { completed: true, abort_reason: None, images_dropped: 0 });
    let names: Vec<&str> = info.attachments.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["camera.toml"]);
    assert_eq!(info.attachments[0].media_type, "application/toml");
    assert_eq!(info.attachments[0].size_bytes, 11);

    let layout = TaxelLayout::from_channel_metadata(&raw.metadata).unwrap().unwrap();
    assert_eq!(layout.device, "sim");
    assert_eq!(layout.fingers.middle, slidetrack_core::FingerReading::taxel("middle", 0));
    assert_eq!(layout.axes, ["x", "y", "z"]);
    let names: Vec<&str> = layout.sensors.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["thumb", "index", "middle"]);
}

#[test]
fn registering_a_topic_twice_returns_the_same_handle_or_fails() {
    let dir = TestDir::new("register");
    let rec = Recorder::create(dir.file("s.mcap"), BTreeMap::new()).unwrap();
    let a = rec.register::<HandCommand>(BTreeMap::new()).unwrap();
    let b = rec.logger().register::<HandCommand>(BTreeMap::new()).unwrap();
    assert_eq!(a, b);
    let meta = BTreeMap::from([("k".to_string(), "v".to_string())]);
    let err = rec.register::<HandCommand>(meta).unwrap_err();
    assert!(matches!(err, SessionError::Channel { ref topic, .. } if topic == "/hand/command"), "{err}");
    rec.finish().unwrap();
}

#[test]
fn csv_has_one_column_per_field_in_struct_order() {
    let (_dir, path, e, _) = recorded("csv", 20);
    let mut out = Vec::new();
    let summary = export_csv(&path, TactileRaw::TOPIC, ReadOptions::default(), &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let mut lines = text.lines();
    // Sensors and their taxels in layout order, each sensor named.
    let header = "log_time_ns,sequence,sensors.0.name,sensors.0.taxels.0.x,sensors.0.taxels.0.y,\
                  sensors.0.taxels.0.z,sensors.1.name,sensors.1.taxels.0.x,sensors.1.taxels.0.y,\
                  sensors.1.taxels.0.z,sensors.2.name,sensors.2.taxels.0.x,sensors.2.taxels.0.y,\
                  sensors.2.taxels.0.z";
    assert_eq!(lines.next(), Some(header));
    assert_eq!(summary.columns.join(","), header);
    assert_eq!(summary.rows, 20);
    let r = &e.raw[3].1;
    let values: Vec<String> = r
        .sensors
        .iter()
        .flat_map(|s| std::iter::once(s.name.clone()).chain(s.taxels[0].to_array().map(|v| v.to_string())))
        .collect();
    let expected = format!("3000000,3,{}", values.join(","));
    assert_eq!(lines.nth(3), Some(expected.as_str()));

    let mut out = Vec::new();
    export_csv(&path, ProtocolEvent::TOPIC, ReadOptions::default(), &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert_eq!(text.lines().nth(1), Some("0,zero,\"zeroing, \"\"hands off\"\"\",false"));
}

#[test]
fn csv_columns_include_fields_that_the_first_message_has_as_null() {
    let (_dir, path, _, _) = recorded("csv-aruco", 40);
    let mut out = Vec::new();
    let summary = export_csv(&path, ArucoDetection::TOPIC, ReadOptions::default(), &mut out).unwrap();
    let expected_columns = [
        "log_time_ns",
        "detected",
        "marker_id",
        "corners_px.0.0",
        "corners_px.0.1",
        "corners_px.1.0",
        "corners_px.1.1",
        "corners_px.2.0",
        "corners_px.2.1",
        "corners_px.3.0",
        "corners_px.3.1",
        "position_in_camera_m.0",
        "position_in_camera_m.1",
        "position_in_camera_m.2",
        "orientation_in_camera.x",
        "orientation_in_camera.y",
        "orientation_in_camera.z",
        "orientation_in_camera.w",
        "position_on_axis_m",
        "reprojection_error_px",
    ];
    assert_eq!(summary.columns, expected_columns);
    let text = String::from_utf8(out).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows.len(), 5);
    assert_eq!(rows[1], format!("0,false{}", ",".repeat(18)));
    assert!(rows[2].starts_with("10000000,true,7,10.5,20.0,30.0,20.25,"), "{}", rows[2]);
}

#[test]
fn csv_refuses_image_channels_and_unknown_topics() {
    let (_dir, path, _, _) = recorded("csv-refuse", 20);
    let err = export_csv(&path, CompressedImage::TOPIC, ReadOptions::default(), Vec::new()).unwrap_err();
    assert!(matches!(err, SessionError::NotTabular { .. }), "{err}");
    assert!(err.to_string().contains("/camera/image"), "{err}");
    let err = export_csv(&path, "/nope", ReadOptions::default(), Vec::new()).unwrap_err();
    assert!(matches!(err, SessionError::NoSuchTopic { .. }), "{err}");
    assert!(err.to_string().contains("/tactile/raw"), "lists the topics there are: {err}");
    let err = read_json::<TactileRaw>(&path, "/nope", ReadOptions::default()).unwrap_err();
    assert!(matches!(err, SessionError::NoSuchTopic { .. }), "{err}");
}

#[test]
fn camera_calibration_keeps_the_intrinsics_and_foxglove_time_splits_seconds() {
    let c = CameraCalibration::from(&intrinsics());
    assert_eq!(c.intrinsics(), Some(intrinsics()));
    assert_eq!(c.distortion_model, "plumb_bob");
    assert_eq!(c.p[0..3], [c.k[0], 0.0, c.k[2]]);
    let t = TimeNs(12_345_678_901);
    let ft = FoxgloveTime::from(t);
    assert_eq!(ft, FoxgloveTime { sec: 12, nsec: 345_678_901 });
    assert_eq!(TimeNs::from(ft), t);
    let json = serde_json::to_value(&c).unwrap();
    for key in ["timestamp", "frame_id", "width", "height", "distortion_model", "D", "K", "R", "P"] {
        assert!(json.get(key).is_some(), "{key}");
    }
}

#[test]
fn session_and_outcome_metadata_round_trip_through_maps() {
    let m = session_metadata();
    assert_eq!(SessionMetadata::from_map(&m.to_map()), Some(m));
    let o = SessionOutcome { completed: false, abort_reason: Some("object fell".into()), images_dropped: 3 };
    assert_eq!(SessionOutcome::from_map(&o.to_map()), Some(o));
}
