//! Eclipse Cyclone DDS (the `cyclonedds` Python binding in target/pyenv),
//! the independent DDS of the ROS 2 tests.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Cyclone DDS on loopback, unicast discovery to the same host's ports.
pub const CYCLONE_LOOPBACK: &str = "<CycloneDDS><Domain id=\"any\"><General><Interfaces>\
    <NetworkInterface address=\"127.0.0.1\"/></Interfaces><AllowMulticast>false</AllowMulticast>\
    </General><Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer address=\"127.0.0.1\"/>\
    </Peers></Discovery></Domain></CycloneDDS>";

/// The project's Python (`SLIDETRACK_PYTHON`, or target/pyenv) when it can
/// import `cyclonedds`; `None` (the test then skips, saying why) otherwise.
pub fn python_with_cyclonedds() -> Option<PathBuf> {
    let python = std::env::var_os("SLIDETRACK_PYTHON")
        .map_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/pyenv/bin/python"), PathBuf::from);
    if !python.exists() {
        eprintln!("skipped: no {} (run scripts/setup.sh --test)", python.display());
        return None;
    }
    let import = Command::new(&python).args(["-c", "import cyclonedds.domain"]).output();
    if !import.is_ok_and(|o| o.status.success()) {
        eprintln!("skipped: {} cannot import cyclonedds (run scripts/setup.sh --test)", python.display());
        return None;
    }
    Some(python)
}
