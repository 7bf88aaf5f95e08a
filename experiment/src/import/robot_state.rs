//! `/robot/state` of imported sessions: the Franka Panda's state as each
//! dataset wrote it. xela-imanlab ([`RobotStateMessage`]) has the
//! end-effector pose as position + quaternion; xela-psc
//! ([`RobotTransformStateMessage`]) has it as a 4x4 matrix, with the
//! commanded Cartesian velocity and the controller's clock.

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use slidetrack_session::Quaternion;

use super::session_parts::{closed_schema, number_array};
use super::xela_csv::RobotState;
use super::xela_psc::PscRobotState;

/// `/robot/state` of xela-imanlab: one row of `robot_state.csv`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotStateMessage {
    /// `position_panda_joint1..7` (rad).
    pub joint_position_rad: [f64; 7],
    /// `velocity_panda_joint1..7` (rad/s).
    pub joint_velocity_rad_s: [f64; 7],
    /// `ee_state_position_{x,y,z}`: end-effector position in the base frame (m).
    pub ee_position_in_base_m: [f64; 3],
    /// `ee_state_orientation_{x,y,z,w}`: base-from-end-effector rotation.
    pub ee_orientation_in_base: Quaternion,
}

impl From<&RobotState> for RobotStateMessage {
    fn from(r: &RobotState) -> RobotStateMessage {
        let [x, y, z, w] = r.ee_orientation_in_base_xyzw;
        RobotStateMessage {
            joint_position_rad: r.joint_position_rad,
            joint_velocity_rad_s: r.joint_velocity_rad_s,
            ee_position_in_base_m: r.ee_position_in_base_m,
            ee_orientation_in_base: Quaternion { x, y, z, w },
        }
    }
}

fn quaternion_schema(description: &str) -> Value {
    let q = |d: &str| -> Value { json!({"type": "number", "description": d}) };
    json!({
        "type": "object",
        "description": description,
        "properties": {"x": q("vector part, x"), "y": q("vector part, y"), "z": q("vector part, z"), "w": q("scalar part")},
        "required": ["x", "y", "z", "w"],
        "additionalProperties": false,
    })
}

/// The JSON Schema of `/robot/state` (xela-imanlab).
pub fn robot_schema() -> Value {
    closed_schema(
        "slidetrack.RobotState",
        json!({
            "joint_position_rad": number_array(7, "joint angles 1..7 (rad)"),
            "joint_velocity_rad_s": number_array(7, "joint velocities 1..7 (rad/s)"),
            "ee_position_in_base_m": number_array(3, "end-effector position in the base frame (m)"),
            "ee_orientation_in_base": quaternion_schema("base-from-end-effector rotation, quaternion"),
        }),
    )
}

/// `/robot/state` of xela-psc: one row of its `robot_state.csv`, every value
/// as written, plus the end-effector pose as position and quaternion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotTransformStateMessage {
    /// `position_joint1..7` (rad).
    pub joint_position_rad: [f64; 7],
    /// `velocity_joint1..7` (rad/s).
    pub joint_velocity_rad_s: [f64; 7],
    /// `ee_T_03, ee_T_13, ee_T_23`: end-effector position in the base frame (m).
    pub ee_position_in_base_m: [f64; 3],
    /// Base-from-end-effector rotation: the rotation nearest the matrix's
    /// 3x3 block (which is orthonormal to ~2e-5 only), scalar part >= 0.
    pub ee_orientation_in_base: Quaternion,
    /// `ee_T_00, ee_T_10, ee_T_20, ee_T_30, ee_T_01, ..., ee_T_33` as written:
    /// the base-from-end-effector transform, column-major (libfranka's `O_T_EE`).
    pub ee_transform_column_major: [f64; 16],
    /// `v_x`: the Cartesian velocity command along the base x axis (m/s).
    pub v_x_m_s: f64,
    /// `v_y`: the Cartesian velocity command along the base y axis (m/s).
    pub v_y_m_s: f64,
    /// `time`: the controller's clock (s, 0 at the first row).
    pub time_s: f64,
}

impl From<&PscRobotState> for RobotTransformStateMessage {
    fn from(r: &PscRobotState) -> RobotTransformStateMessage {
        let [x, y, z, w] = r.ee_orientation_in_base_xyzw();
        RobotTransformStateMessage {
            joint_position_rad: r.joint_position_rad,
            joint_velocity_rad_s: r.joint_velocity_rad_s,
            ee_position_in_base_m: r.ee_position_in_base_m(),
            ee_orientation_in_base: Quaternion { x, y, z, w },
            ee_transform_column_major: r.ee_transform_column_major,
            v_x_m_s: r.v_x_m_s,
            v_y_m_s: r.v_y_m_s,
            time_s: r.time_s,
        }
    }
}

/// The JSON Schema of `/robot/state` (xela-psc).
pub fn robot_transform_schema() -> Value {
    let number = |d: &str| -> Value { json!({"type": "number", "description": d}) };
    closed_schema(
        "slidetrack.RobotTransformState",
        json!({
            "joint_position_rad": number_array(7, "joint angles 1..7 (rad)"),
            "joint_velocity_rad_s": number_array(7, "joint velocities 1..7 (rad/s)"),
            "ee_position_in_base_m": number_array(3, "end-effector position in the base frame (m): ee_T_03, ee_T_13, ee_T_23"),
            "ee_orientation_in_base": quaternion_schema(
                "base-from-end-effector rotation, quaternion: the rotation nearest the transform's 3x3 block, w >= 0"
            ),
            "ee_transform_column_major": number_array(
                16,
                "ee_T_00, ee_T_10, ee_T_20, ee_T_30, ee_T_01, ..., ee_T_33 as written: base-from-end-effector, column-major"
            ),
            "v_x_m_s": number("v_x: Cartesian velocity command along the base x axis (m/s)"),
            "v_y_m_s": number("v_y: Cartesian velocity command along the base y axis (m/s)"),
            "time_s": number("time: the controller's clock (s), as written"),
        }),
    )
}
