//! `slidetrack decode` on captures made from a real XELA uSkin recording
//! (testdata/tactile/xela-imanlab): the recording's rows are encoded as the
//! CAN frames and serial bytes the sensor would have sent, damaged, decoded
//! by the CLI, and the session compared with the recording.

mod common;

use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use common::{fails, ok, tempdir};
use slidetrack_core::{RawTaxel, TimeNs};
use slidetrack_drivers::can::log::candump_line;
use slidetrack_drivers::can::protocol::XelaCanLayout;
use slidetrack_drivers::serial::protocol::ModuleFrame;
use slidetrack_session::{ReadOptions, TactileDecoder, TactileRaw, read_channel};

const SEQUENCE: &str = "test/data_sample_2021-11-25-13-09-52";

fn recording_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/tactile/xela-imanlab").join(SEQUENCE)
}

/// One XELA sensor's rows: 16 taxels of raw (x, y, z) counts each.
fn read_sensor(file: &str) -> Vec<Vec<RawTaxel>> {
    let text = std::fs::read_to_string(recording_dir().join(file)).expect("the XELA recording");
    text.lines()
        .skip(1)
        .map(|line| {
            let v: Vec<u16> =
                line.split(',').map(|x| x.trim().parse::<f64>().expect("a number") as u16).collect();
            assert_eq!(v.len(), 48, "16 taxels x 3 axes");
            v.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
        })
        .collect()
}

/// The recording's start (µs since the epoch) and rate (Hz), from its metadata.
fn start_and_rate() -> (u64, f64) {
    let text =
        std::fs::read_to_string(recording_dir().join("meta_data.csv")).expect("the recording's metadata");
    let mut lines = text.lines().map(|l| l.split(',').collect::<Vec<&str>>());
    let (header, row) = (lines.next().expect("a header"), lines.next().expect("a row"));
    let field = |name: &str| row[header.iter().position(|h| *h == name).expect("the column")];
    let rate: f64 = field("frequency_hz").parse().expect("a rate");
    let start = humantime::parse_rfc3339_weak(field("start_time")).expect("a start time");
    (start.duration_since(UNIX_EPOCH).expect("after 1970").as_micros() as u64, rate)
}

fn have_recording() -> bool {
    let there = recording_dir().join("xela_sensor1.csv").is_file();
    if !there {
        eprintln!("skipping: the XELA recording is not at {}", recording_dir().display());
    }
    there
}

/// A `[[hw.tactile.sensors]]` table: a 4x4 uSkin patch on `module`.
fn patch(name: &str, module: u32, finger: &str) -> String {
    format!(
        "[[hw.tactile.sensors]]\nname = \"{name}\"\nmodule = {module}\nfinger = \"{finger}\"\n\
         model = \"uSPa44\"\nrows = 4\ncols = 4\n"
    )
}

/// The CAN board: one patch, the three fingers reading three of its taxels.
const ONE_PATCH_FINGERS: &str = "fingers = { thumb = { sensor = \"s1\", taxel = 0 }, \
                                 index = { sensor = \"s1\", taxel = 5 }, middle = { sensor = \"s1\" } }";

#[test]
fn a_candump_log_of_a_real_recording_decodes_to_its_values() {
    if !have_recording() {
        return;
    }
    let rows = read_sensor("xela_sensor1.csv");
    let (start_us, rate) = start_and_rate();
    let period_us = 1e6 / rate;
    let layout = XelaCanLayout::default();
    let mut lines = vec![candump_line(start_us, "can0", &layout.start_command())];
    for (i, row) in rows.iter().enumerate() {
        let t0 = start_us + 1000 + (i as f64 * period_us) as u64;
        for (t, v) in row.iter().enumerate() {
            if i == 10 && t == 7 {
                continue; // a lost frame: scan 10 is dropped
            }
            lines.push(candump_line(t0 + 120 * t as u64, "can0", &layout.taxel_frame(t as u16, *v, true)));
        }
        if i == 20 {
            lines.push("(1637845790.0) can0 710#00".into()); // a corrupt line
        }
        if i == 30 {
            let n = lines.len();
            lines.swap(n - 3, n - 9); // frames reordered within scan 30
        }
        if i == 40 {
            // the hand's set-point on the same bus
            lines.push(format!("({}.{:06}) can0 300#00000000000000", t0 / 1_000_000, t0 % 1_000_000));
        }
    }
    lines.truncate(lines.len() - 5); // the capture ends inside the last scan
    let dir = tempdir();
    let log = dir.path().join("xela.log");
    std::fs::write(&log, lines.join("\n") + "\n").unwrap();
    let rig = dir.path().join("rig.toml");
    let sensors = patch("s1", 0, "thumb");
    let table = format!(
        "[hw.tactile]\nkind = \"can\"\ntaxels = 16\nrate_hz = {rate}\n{ONE_PATCH_FINGERS}\n{sensors}"
    );
    std::fs::write(&rig, table).unwrap();
    let out = dir.path().join("xela.mcap");
    let p = |p: &Path| p.to_str().unwrap().to_string();
    let summary = ok(&["-q", "decode", "--can-log", &p(&log), "--config", &p(&rig), "--out", &p(&out)]);
    assert!(summary.contains("scans"), "{summary}");

    let raw = read_channel::<TactileRaw>(&out, ReadOptions::default()).unwrap();
    let kept: Vec<usize> = (0..rows.len() - 1).filter(|&i| i != 10).collect();
    assert_eq!(raw.len(), kept.len());
    for ((t, msg), &i) in raw.iter().zip(&kept) {
        // Every taxel of the patch, as recorded.
        assert_eq!(msg.sensors.len(), 1);
        let got: Vec<RawTaxel> = msg.sensors[0].taxels.iter().map(|v| v.to_array()).collect();
        assert_eq!(got, rows[i], "row {i}");
        let expected_us = 1000.0 + i as f64 * period_us + 120.0 * 15.0;
        assert!((t.0 as f64 / 1e3 - expected_us).abs() < 2.0, "row {i}: {t:?} vs {expected_us} us");
    }
    let counters = read_channel::<TactileDecoder>(&out, ReadOptions::default()).unwrap();
    let (_, last) = counters.last().unwrap();
    assert_eq!(last.incomplete_scans, 1);
    assert_eq!(last.frames, (rows.len() * 16 - 1 - 5) as u64);

    let info: serde_json::Value = serde_json::from_str(&ok(&["info", &p(&out), "--json"])).unwrap();
    let source = &info["metadata"]["slidetrack.source"];
    assert_eq!(source["kind"], "can-log");
    assert_eq!(source["timing"], "capture timestamps");
    assert_eq!(info["metadata"]["slidetrack"]["rig"], "decoded");
    let raw_ch = info["channels"].as_array().unwrap().iter().find(|c| c["topic"] == "/tactile/raw").unwrap();
    assert!((raw_ch["rate_hz"].as_f64().unwrap() - rate).abs() < 1.0, "{raw_ch}");
}

#[test]
fn a_serial_capture_of_a_real_recording_decodes_despite_damage() {
    if !have_recording() {
        return;
    }
    let (s1, s2) = (read_sensor("xela_sensor1.csv"), read_sensor("xela_sensor2.csv"));
    let mut bytes = vec![0x42, 0x5A, 0xA5]; // the capture began mid-stream
    let mut damaged = Vec::new();
    for (i, (a, b)) in s1.iter().zip(&s2).enumerate() {
        for (module, row) in [(0u8, a), (1u8, b)] {
            let start = bytes.len();
            ModuleFrame::new(module, i as u16, row).unwrap().encode_into(&mut bytes);
            if i == 50 && module == 0 {
                bytes[start + 40] ^= 0x01; // a flipped bit: scan 50 is lost
                damaged.push(i);
            }
        }
        if i == 80 {
            bytes.extend_from_slice(b"noise \xA5\x5A\x00\x06 \xA5"); // garbage with a false sync
        }
    }
    bytes.truncate(bytes.len() - 30); // cut inside the last frame
    damaged.push(s1.len() - 1);
    let dir = tempdir();
    let capture = dir.path().join("capture.bin");
    std::fs::write(&capture, &bytes).unwrap();
    let rig = dir.path().join("rig.toml");
    let fingers = "fingers = { thumb = { sensor = \"s1\", taxel = 3 }, index = { sensor = \"s2\", taxel = 3 }, \
                   middle = { sensor = \"s2\" } }";
    let sensors = patch("s1", 0, "thumb") + &patch("s2", 1, "index");
    std::fs::write(&rig, format!("[hw.tactile]\nkind = \"serial\"\n{fingers}\n{sensors}")).unwrap();
    let out = dir.path().join("capture.mcap");
    let p = |p: &Path| p.to_str().unwrap().to_string();
    ok(&[
        "-q",
        "decode",
        "--serial-capture",
        &p(&capture),
        "--config",
        &p(&rig),
        "--rate",
        "37.959",
        "--out",
        &p(&out),
    ]);

    let raw = read_channel::<TactileRaw>(&out, ReadOptions::default()).unwrap();
    let kept: Vec<usize> = (0..s1.len()).filter(|i| !damaged.contains(i)).collect();
    assert_eq!(raw.len(), kept.len());
    for ((t, msg), &i) in raw.iter().zip(&kept) {
        assert_eq!(msg.sequence, i as u64);
        // Both patches, every taxel: the 96 values of the recording's row.
        let got: Vec<RawTaxel> =
            msg.sensors.iter().flat_map(|s| s.taxels.iter().map(|v| v.to_array())).collect();
        assert_eq!(got, [s1[i].clone(), s2[i].clone()].concat(), "row {i}");
        assert_eq!(*t, TimeNs((i as f64 / 37.959 * 1e9).round() as u64));
    }
    let (_, last) = read_channel::<TactileDecoder>(&out, ReadOptions::default()).unwrap().pop().unwrap();
    assert_eq!((last.crc_errors, last.incomplete_scans), (1, 1), "{last:?}");
    assert_eq!(last.resyncs, 3, "start, after the bad CRC, after the garbage: {last:?}");
    assert_eq!(last.gaps, 1, "module 0 lost scan 50");
}

#[test]
fn decode_refuses_bad_input_with_one_clear_line() {
    let dir = tempdir();
    let out = dir.path().join("out.mcap");
    let out_s = out.to_str().unwrap();
    let e = fails(&["decode", "--can-log", "/no/such.log", "--out", out_s]);
    assert!(e.contains("/no/such.log"), "{e}");
    let empty = dir.path().join("empty.log");
    std::fs::write(&empty, "not a candump log\n").unwrap();
    let e = fails(&["-q", "decode", "--can-log", empty.to_str().unwrap(), "--out", out_s]);
    assert!(e.contains("no scan decoded") && e.contains("1 unreadable"), "{e}");
    let e = fails(&["-q", "decode", "--can-log", empty.to_str().unwrap(), "--out", out_s]);
    assert!(e.contains("already exists") && e.contains("--overwrite"), "{e}");
    let out2 = dir.path().join("out2.mcap");
    let out2 = out2.to_str().unwrap();
    let e =
        fails(&["-q", "decode", "--serial-capture", empty.to_str().unwrap(), "--rate", "0", "--out", out2]);
    assert!(e.contains("--rate"), "{e}");
    let e = fails(&["-q", "decode", "--can-log", empty.to_str().unwrap(), "--taxels", "0", "--out", out2]);
    assert!(e.contains("taxels"), "{e}");
}

/// candump's console output (no times) of two 2x2 patches in an explicit
/// id map with little-endian values: decoded with the rig's layout, every
/// value kept, in log order.
#[test]
fn plain_candump_output_decodes_in_a_configured_map_layout() {
    use slidetrack_drivers::can::candump::plain::format_plain_line;
    let value = |s: u16, k: u16| [100 + s, 200 + k, 300 + s * k];
    let mut lines = vec![format_plain_line(None, "can0", 0x300, false, &[9, 9])]; // an unmapped id
    for s in 0..6u16 {
        for k in 0..8u16 {
            if s == 2 && k == 3 {
                continue; // a lost frame: scan 2 is dropped
            }
            // Sensor a at 0x400 + 0x10 row + col, sensor b at 0x500, 0x502, ...
            let id = if k < 4 {
                0x400 + 0x10 * u32::from(k / 2) + u32::from(k % 2)
            } else {
                0x500 + 2 * u32::from(k - 4)
            };
            let data: Vec<u8> = value(s, k).iter().flat_map(|v| v.to_le_bytes()).collect();
            lines.push(format_plain_line(None, "can0", id, false, &data));
        }
    }
    lines.push("  can0  4A0   [8]  remote request".into());
    lines.push("this line is not candump output".into());
    let dir = tempdir();
    let log = dir.path().join("dump.txt");
    std::fs::write(&log, lines.join("\n") + "\n").unwrap();
    let rig = dir.path().join("rig.toml");
    let sensor = |name: &str, module: u32| {
        format!(
            "[[hw.tactile.sensors]]\nname = \"{name}\"\nmodule = {module}\nfinger = \"thumb\"\nmodel = \"uSPa22\"\nrows = 2\ncols = 2\n"
        )
    };
    let table = format!(
        "[hw.tactile]\nkind = \"can\"\nfingers = {{ thumb = {{ sensor = \"a\" }}, index = {{ sensor = \"b\" }}, \
         middle = {{ sensor = \"b\", taxel = 3 }} }}\npayload = {{ byte_order = \"little\", x = 0, y = 2, z = 4 }}\n\
         {}{}[[hw.tactile.map]]\nsensor = \"a\"\nbase_id = 0x400\nrow_stride = 0x10\n\
         [[hw.tactile.map]]\nsensor = \"b\"\nfirst_id = 0x500\nid_step = 2\n",
        sensor("a", 0),
        sensor("b", 1)
    );
    std::fs::write(&rig, table).unwrap();
    let out = dir.path().join("dump.mcap");
    let p = |p: &Path| p.to_str().unwrap().to_string();
    let summary = ok(&["-q", "decode", "--can-log", &p(&log), "--config", &p(&rig), "--out", &p(&out)]);
    assert!(summary.contains("5 scans") && summary.contains("1 unreadable"), "{summary}");
    let raw = read_channel::<TactileRaw>(&out, ReadOptions::default()).unwrap();
    let scans: Vec<u16> = vec![0, 1, 3, 4, 5];
    assert_eq!(raw.len(), scans.len());
    for ((_, msg), &s) in raw.iter().zip(&scans) {
        let got: Vec<RawTaxel> =
            msg.sensors.iter().flat_map(|x| x.taxels.iter().map(|v| v.to_array())).collect();
        assert_eq!(got, (0..8).map(|k| value(s, k)).collect::<Vec<_>>(), "scan {s}");
    }
    let (_, last) = read_channel::<TactileDecoder>(&out, ReadOptions::default()).unwrap().pop().unwrap();
    assert_eq!((last.incomplete_scans, last.frames), (1, 47));
    let info: serde_json::Value = serde_json::from_str(&ok(&["info", &p(&out), "--json"])).unwrap();
    let timing = info["metadata"]["slidetrack.source"]["timing"].as_str().unwrap().to_string();
    assert!(timing.starts_with("log order"), "{timing}");
}
