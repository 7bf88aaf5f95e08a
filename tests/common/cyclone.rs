//! Eclipse Cyclone DDS (the `cyclonedds` Python binding in target/pyenv),
//! the independent DDS of the ROS 2 tests.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use serde_json::Value;

/// Cyclone DDS on loopback, unicast discovery to the same host's ports.
pub const CYCLONE_LOOPBACK: &str = "<CycloneDDS><Domain id=\"any\"><General><Interfaces>\
    <NetworkInterface address=\"127.0.0.1\"/></Interfaces><AllowMulticast>false</AllowMulticast>\
    </General><Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer address=\"127.0.0.1\"/>\
    </Peers></Discovery></Domain></CycloneDDS>";

/// The project's Python (`SLIDETRACK_PYTHON`, or target/pyenv) when it can
/// import `cyclonedds`; `None` (the test then skips, saying why) otherwise.
pub fn python_with_cyclonedds() -> Option<PathBuf> {
    super::python_importing("cyclonedds.domain", "cyclonedds")
}

/// Starts `tests/python/SCRIPT DOMAIN` on Cyclone DDS over loopback and
/// waits until it says `ready` on stderr (its readers or writers exist).
pub fn start_ready(python: &Path, script: &str, domain: u32) -> Child {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python").join(script);
    let mut child = Command::new(python)
        .arg(path)
        .arg(domain.to_string())
        .env("CYCLONEDDS_URI", CYCLONE_LOOPBACK)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python runs");
    let mut stderr = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    stderr.read_line(&mut line).unwrap_or_else(|e| panic!("{script}: its first line: {e}"));
    assert_eq!(line.trim(), "ready", "{script} did not start: {line}");
    child
}

/// Closes the stdin of a script started by [`start_ready`] (which ends
/// it) and returns what it printed, one JSON value per line.
pub fn stop_and_read(mut child: Child) -> Vec<Value> {
    drop(child.stdin.take());
    let out = child.wait_with_output().expect("the script ends");
    assert!(out.status.success(), "the script failed");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect()
}

/// A DDS domain id of the calling test alone while the returned lock lives:
/// the first of 10..=230 whose lock file in the target's test directory it
/// can lock. Tests run as threads of one process (`cargo test`) or as
/// processes of their own (`cargo nextest`), in several test binaries at
/// once; a domain each keeps one test's participants from another's data.
pub fn lease_domain() -> (u32, std::fs::File) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("dds-domains");
    std::fs::create_dir_all(&dir).expect("the DDS domains' lock directory");
    for domain in 10..=230u32 {
        let file = std::fs::File::create(dir.join(format!("{domain}.lock"))).expect("a domain's lock file");
        if file.try_lock().is_ok() {
            return (domain, file);
        }
    }
    panic!("every DDS domain 10-230 is held by another test");
}
