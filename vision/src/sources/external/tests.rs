//! The external source on a local socket: well-formed, corrupted and
//! truncated messages, reconnection, late results, unknown frames, lockstep.

use std::io::{BufRead, BufReader, Lines, Write};
use std::net::TcpStream;
use std::time::Duration;

use serde_json::{Value, json};
use slidetrack_core::{CameraIntrinsics, DepthImage, Image, PixelFormat, RgbdFrame, TimeNs};

use super::*;

const W: u32 = 8;
const H: u32 = 6;

fn intrinsics() -> CameraIntrinsics {
    CameraIntrinsics { width: W, height: H, fx: 10.0, fy: 10.0, cx: 3.5, cy: 2.5, distortion: [0.0; 5] }
}

fn frame(t_ns: u64) -> RgbdFrame {
    RgbdFrame {
        t: TimeNs(t_ns),
        sequence: t_ns,
        color: Image::zeros(W, H, PixelFormat::Rgb8),
        depth: DepthImage { width: W, height: H, data: vec![0; (W * H) as usize], scale_m: 0.001 },
        intrinsics: intrinsics(),
    }
}

fn source(wait: Option<Duration>, max_age_ns: u64) -> ExternalSource {
    let config = ExternalConfig {
        listen: "127.0.0.1:0".into(),
        wait_for_result: wait,
        wait_for_client: None,
        max_age_ns,
        send_images: false,
    };
    ExternalSource::listen(config, &intrinsics()).unwrap()
}

/// Feeds frames 1 ms apart from `t` until `done` (at most 2 s).
fn pump(src: &mut ExternalSource, t: &mut u64, done: impl Fn(&ExternalSource) -> bool) -> Arrivals {
    let mut all = Arrivals::default();
    for _ in 0..400 {
        if done(src) {
            return all;
        }
        *t += 1_000_000;
        let a = src.on_rgbd_frame(&frame(*t), None).unwrap();
        all.poses.extend(a.poses);
        all.masks.extend(a.masks);
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!("timed out; stats {:?}, last error {:?}", src.stats(), src.last_error());
}

struct Client {
    writer: TcpStream,
    lines: Lines<BufReader<TcpStream>>,
}

impl Client {
    /// Connects and completes the handshake with `version`.
    fn connect(src: &ExternalSource, version: u32) -> Client {
        let stream = TcpStream::connect(src.local_addr()).unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let writer = stream.try_clone().unwrap();
        let mut client = Client { writer, lines: BufReader::new(stream).lines() };
        let hello = client.next();
        assert_eq!(
            (hello["type"].as_str(), hello["version"].as_u64(), hello["width"].as_u64()),
            (Some("hello"), Some(1), Some(8))
        );
        client.send(&json!({"type": "hello", "protocol": "slidetrack-vision-source", "version": version, "name": "test"}));
        client
    }

    fn next(&mut self) -> Value {
        serde_json::from_str(&self.lines.next().unwrap().unwrap()).unwrap()
    }

    /// The next message of `kind`.
    fn next_of(&mut self, kind: &str) -> Value {
        loop {
            let m = self.next();
            if m["type"] == kind {
                return m;
            }
        }
    }

    fn send(&mut self, message: &Value) {
        writeln!(self.writer, "{message}").unwrap();
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.writer.write_all(bytes).unwrap();
    }
}

fn result(frame_t_ns: u64, x_m: f64) -> Value {
    json!({
        "type": "result",
        "frame_t_ns": frame_t_ns,
        "pose": {"translation_m": [x_m, 0.0, 0.5], "rotation_xyzw": [0.0, 0.0, 0.0, 1.0]},
        // Pixels 3 and 4 of the first row.
        "mask": {"encoding": "rle", "width": W, "height": H, "counts": [3, 2, W * H - 5]},
    })
}

#[test]
fn a_well_formed_result_arrives_with_its_frame_time() {
    let mut src = source(None, 1_000_000_000);
    let mut t = 0;
    let mut client = Client::connect(&src, 1);
    pump(&mut src, &mut t, |s| s.stats().connections == 1);
    let frame_t = client.next_of("frame")["frame_t_ns"].as_u64().unwrap();
    client.send(&result(frame_t, 0.25));
    let got = pump(&mut src, &mut t, |s| s.stats().poses == 1);
    assert_eq!(got.poses.len(), 1);
    assert_eq!(got.poses[0].frame_t, TimeNs(frame_t));
    assert!(got.poses[0].arrival_t.0 > frame_t);
    assert!((got.poses[0].value.translation.x - 0.25).abs() < 1e-12);
    let mask = &got.masks[0].value;
    assert!(mask.contains(3, 0) && mask.contains(4, 0) && !mask.contains(2, 0) && !mask.contains(5, 0));
    assert_eq!(src.stats().refused, 0);
}

#[test]
fn corrupted_and_truncated_messages_are_refused_and_a_client_can_reconnect() {
    let mut src = source(None, 1_000_000_000);
    let mut t = 0;
    let mut client = Client::connect(&src, 1);
    pump(&mut src, &mut t, |s| s.stats().connections == 1);
    let frame_t = client.next_of("frame")["frame_t_ns"].as_u64().unwrap();
    client.send_raw(b"not json\n");
    client.send(&json!({"type": "result"}));
    client.send(&json!({"type": "result", "frame_t_ns": frame_t, "mask": {"encoding": "rle", "width": W, "height": H, "counts": [3]}}));
    client.send(&json!({"type": "result", "frame_t_ns": frame_t, "mask": {"encoding": "rle", "width": 4, "height": 4, "counts": [16]}}));
    client.send(&json!({"type": "result", "frame_t_ns": frame_t, "pose": {"translation_m": [0, 0, 1], "rotation_xyzw": [0, 0, 0, 2]}}));
    client.send(&result(frame_t, 0.1));
    pump(&mut src, &mut t, |s| s.stats().poses == 1);
    assert_eq!(src.stats().refused, 5, "{:?}", src.last_error());
    let kinds: Vec<String> =
        (0..5).map(|_| client.next_of("error")["kind"].as_str().unwrap().to_string()).collect();
    assert_eq!(kinds, ["bad_message", "bad_message", "bad_mask", "bad_mask", "bad_pose"]);
    // Half a message, then the client goes away.
    client.send_raw(br#"{"type": "result", "frame_t"#);
    drop(client);
    pump(&mut src, &mut t, |s| s.stats().disconnections == 1);
    assert_eq!(src.stats().refused, 6);
    assert!(src.last_error().unwrap().contains("inside a message"), "{:?}", src.last_error());
    // The tracker went on; a new client is heard.
    let mut client = Client::connect(&src, 1);
    pump(&mut src, &mut t, |s| s.stats().connections == 2);
    let frame_t = client.next_of("frame")["frame_t_ns"].as_u64().unwrap();
    client.send(&result(frame_t, 0.2));
    let got = pump(&mut src, &mut t, |s| s.stats().poses == 2);
    assert_eq!(got.poses[0].frame_t, TimeNs(frame_t));
}

#[test]
fn late_results_and_results_for_unknown_frames_are_dropped() {
    let mut src = source(None, 50_000_000);
    let mut t = 0;
    let mut client = Client::connect(&src, 1);
    pump(&mut src, &mut t, |s| s.stats().connections == 1);
    let old = client.next_of("frame")["frame_t_ns"].as_u64().unwrap();
    // 100 ms of frames later.
    let until = old + 100_000_000;
    for k in 1..=100 {
        src.on_rgbd_frame(&frame(t + k * 1_000_000), None).unwrap();
    }
    t += 100 * 1_000_000;
    assert!(t >= until);
    client.send(&result(old, 0.0));
    client.send(&result(123, 0.0));
    let got = pump(&mut src, &mut t, |s| s.stats().late == 1 && s.stats().unknown_frames == 1);
    assert!(got.poses.is_empty());
    let kinds = [client.next_of("error")["kind"].clone(), client.next_of("error")["kind"].clone()];
    assert_eq!(kinds, [json!("late"), json!("unknown_frame")]);
}

#[test]
fn a_client_of_another_version_is_refused_and_closed() {
    let mut src = source(None, 1_000_000_000);
    let mut t = 0;
    let mut client = Client::connect(&src, 2);
    let error = client.next_of("error");
    assert_eq!(error["kind"], "bad_handshake");
    assert!(client.lines.next().is_none(), "the server closes the connection");
    pump(&mut src, &mut t, |s| s.stats().refused == 1);
    assert_eq!(src.stats().connections, 0);
}

#[test]
fn in_lockstep_each_frame_gets_its_own_result() {
    let mut src = source(Some(Duration::from_secs(5)), 1_000_000_000);
    let addr = src.local_addr();
    let answering = std::thread::Builder::new()
        .name("test-client".into())
        .spawn(move || {
            let stream = TcpStream::connect(addr).unwrap();
            let mut writer = stream.try_clone().unwrap();
            let mut lines = BufReader::new(stream).lines();
            lines.next();
            writeln!(
                writer,
                "{}",
                json!({"type": "hello", "protocol": "slidetrack-vision-source", "version": 1})
            )
            .unwrap();
            let mut answered = 0;
            for line in lines {
                let m: Value = serde_json::from_str(&line.unwrap()).unwrap();
                let t = m["frame_t_ns"].as_u64().unwrap();
                // Only the frames of the lockstep part.
                if t < 1_000_000_000 {
                    continue;
                }
                writeln!(writer, "{}", result(t, t as f64 * 1e-9)).unwrap();
                answered += 1;
                if answered == 3 {
                    return answered;
                }
            }
            answered
        })
        .unwrap();
    let mut t = 0;
    pump(&mut src, &mut t, |s| s.stats().connections == 1);
    for k in 1..=3u64 {
        let t_k = 1_000_000_000 + k * 33_000_000;
        let got = src.on_rgbd_frame(&frame(t_k), None).unwrap();
        let mine: Vec<_> = got.poses.iter().filter(|p| p.frame_t == TimeNs(t_k)).collect();
        assert_eq!(mine.len(), 1, "frame {k}: {got:?}");
        assert_eq!(mine[0].arrival_t, TimeNs(t_k));
    }
    assert_eq!(answering.join().unwrap(), 3);
}

#[test]
fn png_and_rle_masks_decode_to_the_same_pixels() {
    let mut pixels = vec![0u8; (W * H) as usize];
    pixels[3] = 255;
    pixels[4] = 1;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, W, H);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header().unwrap().write_image_data(&pixels).unwrap();
    let png = MaskMessage::Png { data: base64::engine::general_purpose::STANDARD.encode(&bytes) };
    let rle = MaskMessage::Rle { width: W, height: H, counts: vec![3, 2, u64::from(W * H) - 5] };
    assert_eq!(protocol::decode_mask(&png, 1, W, H).unwrap(), protocol::decode_mask(&rle, 1, W, H).unwrap());
    let garbage = MaskMessage::Png { data: "AAAA".into() };
    assert!(matches!(
        protocol::decode_mask(&garbage, 7, W, H),
        Err(ExternalError::BadMask { frame_t_ns: 7, .. })
    ));
}

#[test]
fn frames_carry_their_images_when_asked() {
    let config = ExternalConfig {
        listen: "127.0.0.1:0".into(),
        wait_for_result: None,
        wait_for_client: Some(Duration::from_secs(5)),
        max_age_ns: 1_000_000_000,
        send_images: true,
    };
    let mut src = ExternalSource::listen(config, &intrinsics()).unwrap();
    let mut client = Client::connect(&src, 1);
    let mut f = frame(1_000);
    f.depth.data[9] = 1234;
    // The source waits for the client before its first frame: that one is announced.
    src.on_rgbd_frame(&f, None).unwrap();
    let m = client.next_of("frame");
    assert_eq!(m["frame_t_ns"], 1_000);
    let b64 = |key: &str| base64::engine::general_purpose::STANDARD.decode(m[key].as_str().unwrap()).unwrap();
    let jpeg = b64("color_jpeg");
    assert_eq!(&jpeg[..2], &[0xff, 0xd8], "a JPEG");
    let png_bytes = b64("depth_png");
    let mut reader = png::Decoder::new(std::io::Cursor::new(png_bytes)).read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!((info.width, info.height, info.bit_depth), (W, H, png::BitDepth::Sixteen));
    assert_eq!(u16::from_be_bytes([buffer[18], buffer[19]]), 1234, "millimetres, big-endian");
    assert_eq!(src.stats().connections, 1);
}
