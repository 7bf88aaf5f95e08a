//! The independent ROS 2 bag reader of the bag tests: `rosbags` in the
//! project's Python (tests/python/check_ros2_bag.py).

use std::path::{Path, PathBuf};

use super::ok;

/// The project's Python (`SLIDETRACK_PYTHON`, or target/pyenv) when it can
/// import `rosbags`; `None` (the test then skips, saying why) otherwise.
pub fn python_with_rosbags() -> Option<PathBuf> {
    super::python_importing("rosbags, mcap", "rosbags")
}

/// Exports `session` to a bag beside it and checks it with rosbags: every
/// converted message is in the bag, in order, with the session's values.
/// Returns the messages compared per session topic.
pub fn export_and_check(python: &Path, session: &Path) -> serde_json::Value {
    let bag = session.with_extension("ros2.mcap");
    let path = |p: &Path| p.to_str().expect("utf-8 path").to_string();
    ok(&["-q", "export", &path(session), "--ros2-bag", &path(&bag)]);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::process::Command::new(python)
        .arg(root.join("tests/python/check_ros2_bag.py"))
        .args([&bag, session, &root.join("session/ros2/slidetrack_msgs/msg")])
        .output()
        .expect("python runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "check_ros2_bag: {stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_str(&stdout).expect("summary")
}
