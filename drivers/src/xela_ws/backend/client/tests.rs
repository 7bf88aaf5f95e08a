//! The client against the emulator, end to end over loopback TCP.

use std::time::{Duration, Instant};

use slidetrack_core::ErrorKind;

use super::*;
use crate::xela_ws::backend::emulator::{XelaWsEmulator, XelaWsEmulatorConfig, synthetic_scans};
use crate::xela_ws::protocol::{ExpectedSensor, WireStyle, encode_scan};

const PERIOD: Duration = Duration::from_millis(2);
const WAIT: Duration = Duration::from_secs(2);

fn sensors() -> Vec<ExpectedSensor> {
    vec![
        ExpectedSensor { sensor: 1, model: "uSPa44".into(), taxels: 16 },
        ExpectedSensor { sensor: 2, model: "uSPa46".into(), taxels: 24 },
    ]
}

fn options() -> XelaWsOptions {
    XelaWsOptions {
        expected: Some(Expected { sensors: sensors() }),
        reconnect: ReconnectPolicy {
            initial_backoff: Duration::from_millis(5),
            max_backoff: Duration::from_millis(40),
            max_attempts: 5,
            max_duration: Duration::from_millis(500),
        },
        ..XelaWsOptions::default()
    }
}

fn start(config: XelaWsEmulatorConfig) -> (XelaWsEmulator, XelaWsClient) {
    let emulator = XelaWsEmulator::start(config).expect("emulator");
    let client = XelaWsClient::connect(&emulator.url(), options()).expect("connect");
    (emulator, client)
}

/// Reads `n` scans, each within [`WAIT`].
fn read(client: &mut XelaWsClient, n: usize) -> Vec<XelaReceived> {
    (0..n).map(|i| client.next_scan(WAIT).unwrap_or_else(|e| panic!("scan {i}: {e}"))).collect()
}

#[test]
fn every_scan_arrives_in_order_whatever_the_encoding() {
    let scans = synthetic_scans(100, 30, &sensors(), true);
    let styles = [WireStyle::HexString, WireStyle::IntegerList, WireStyle::HexAndInteger];
    let texts = scans.iter().enumerate().map(|(i, s)| encode_scan(s, styles[i % 3])).collect();
    let (_emulator, mut client) = start(XelaWsEmulatorConfig::texts(texts, PERIOD));
    let got = read(&mut client, scans.len());
    assert_eq!(got.iter().map(|r| &r.scan).collect::<Vec<_>>(), scans.iter().collect::<Vec<_>>());
    assert!(got.windows(2).all(|w| w[0].arrival <= w[1].arrival));
    assert!(got.iter().all(|r| r.gap.is_none()));
    assert_eq!(client.welcome().and_then(|w| w.version.as_deref()), Some("emulator"));
    let c = client.counters();
    assert_eq!((c.messages, c.welcomes, c.scans, c.malformed, c.gaps, c.reconnects), (31, 1, 30, 0, 0, 0));
}

#[test]
fn a_stalled_server_times_out_and_the_stream_goes_on_after() {
    let scans = synthetic_scans(1, 3, &sensors(), false);
    let mut config = XelaWsEmulatorConfig::replay(&scans, WireStyle::HexString, PERIOD);
    config.messages[2].delay = Duration::from_millis(400);
    let (_emulator, mut client) = start(config);
    read(&mut client, 2);
    let t = Instant::now();
    let e = client.next_scan(Duration::from_millis(100)).expect_err("a stall");
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(t.elapsed() >= Duration::from_millis(100) && t.elapsed() < Duration::from_millis(350));
    assert_eq!(read(&mut client, 1)[0].scan.message, 3, "a timeout is not final");
    let e = client.next_scan(Duration::from_millis(50)).expect_err("the end of the script");
    assert_eq!(e.kind, ErrorKind::Timeout);
}

#[test]
fn the_client_reconnects_after_a_dropped_connection() {
    let scans = synthetic_scans(1, 12, &sensors(), true);
    let mut config = XelaWsEmulatorConfig::replay(&scans, WireStyle::IntegerList, PERIOD);
    config.disconnect_after = vec![4, 9];
    let (emulator, mut client) = start(config);
    let got = read(&mut client, scans.len());
    assert_eq!(got.iter().map(|r| r.scan.message).collect::<Vec<_>>(), (1..=12).collect::<Vec<_>>());
    assert_eq!((emulator.connections(), client.counters().reconnects, client.counters().welcomes), (3, 2, 3));
}

#[test]
fn counter_gaps_are_reported_with_the_scan() {
    let mut scans = synthetic_scans(1, 6, &sensors(), false);
    scans[3].message = 9; // 1 2 3 9 5 6: a skip, then the counter goes back
    let (_emulator, mut client) = start(XelaWsEmulatorConfig::replay(&scans, WireStyle::HexString, PERIOD));
    let gaps: Vec<_> = read(&mut client, 6).into_iter().map(|r| r.gap).collect();
    assert_eq!(gaps[3], Some(MessageGap::Skip { expected: 4, got: 9 }));
    assert_eq!(gaps[4], Some(MessageGap::Backward { previous: 9, got: 5 }));
    let c = client.counters();
    assert_eq!((c.gaps, c.lost_messages, c.backward), (2, 5, 1));
}

#[test]
fn malformed_messages_are_counted_and_skipped() {
    let scans = synthetic_scans(1, 4, &sensors(), false);
    let mut texts: Vec<String> = scans.iter().map(|s| encode_scan(s, WireStyle::HexString)).collect();
    texts.insert(1, "{\"message\": 2, \"1\": {\"model\"".into());
    texts.insert(3, "[]".into());
    texts.insert(5, encode_scan(&scans[2], WireStyle::HexString).replace("\"data\":\"", "\"data\":\"ZZZZ,"));
    let (_emulator, mut client) = start(XelaWsEmulatorConfig::texts(texts, PERIOD));
    let got = read(&mut client, 4);
    assert_eq!(got.iter().map(|r| r.scan.message).collect::<Vec<_>>(), [1, 2, 3, 4]);
    assert_eq!((client.counters().malformed, client.counters().scans), (3, 4));
}

#[test]
fn a_model_mismatch_is_a_final_error_naming_the_setting() {
    let mut scans = synthetic_scans(1, 3, &sensors(), false);
    scans[1].sensors[1].model = "uSPa44".into();
    let (_emulator, mut client) =
        start(XelaWsEmulatorConfig::replay(&scans, WireStyle::HexAndInteger, PERIOD));
    read(&mut client, 1);
    let e = client.next_scan(WAIT).expect_err("a mismatch");
    assert_eq!(e.kind, ErrorKind::Other);
    for part in ["sensor 2", "uSPa46", "uSPa44", "`model`", "[sensor2]"] {
        assert!(e.detail.contains(part), "{part} in {e}");
    }
    assert!(!e.to_string().contains('\n'));
    assert_eq!(client.next_scan(WAIT), Err(e), "final");
}

#[test]
fn a_server_gone_for_good_is_disconnected() {
    let scans = synthetic_scans(1, 5, &sensors(), false);
    let mut config = XelaWsEmulatorConfig::replay(&scans, WireStyle::HexString, PERIOD);
    config.disconnect_after = vec![2];
    config.accept_reconnect = false;
    let (_emulator, mut client) = start(config);
    read(&mut client, 2);
    let t = Instant::now();
    let e = loop {
        match client.next_scan(Duration::from_millis(50)) {
            Err(e) if e.kind == ErrorKind::Timeout => assert!(t.elapsed() < WAIT, "{e}"),
            other => break other.expect_err("no scan from a server that is gone"),
        }
    };
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(e.detail.contains("attempts"), "{e}");
    assert_eq!(client.next_scan(WAIT), Err(e), "final");
}

#[test]
fn an_unreachable_server_and_unusable_urls_fail_to_connect() {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let Err(e) = XelaWsClient::connect(&format!("ws://127.0.0.1:{port}"), options()) else {
        panic!("nobody listens")
    };
    assert_eq!(e.kind, ErrorKind::Disconnected);
    assert!(e.detail.contains("--ip"), "{e}");
    for url in ["wss://127.0.0.1:5000", "http://127.0.0.1:5000", "not a url"] {
        let Err(e) = XelaWsClient::connect(url, options()) else { panic!("{url}") };
        assert_eq!(e.kind, ErrorKind::Other, "{url}: {e}");
    }
    assert_eq!(target("ws://192.168.0.21").unwrap(), ("192.168.0.21".to_string(), 5000));
    assert_eq!(target("ws://[::1]:5001").unwrap(), ("::1".to_string(), 5001));
}

#[test]
fn the_backoff_doubles_up_to_its_limit() {
    let p = ReconnectPolicy::default();
    let ms = |n| p.backoff(n).as_millis();
    assert_eq!([ms(1), ms(2), ms(3), ms(5), ms(6), ms(40)], [100, 200, 400, 1600, 2000, 2000]);
}
