//! ROS 2 messages in CDR (little endian, with the 4-byte encapsulation header): the schema texts
//! (`ros2msg`) and the serde types the `cdr` crate serializes. Only the two message types the sink
//! writes: `sensor_msgs/msg/JointState` and `std_msgs/msg/String`.

use serde::Serialize;

/// Schema name of the envelope and error channels.
pub const JOINT_STATE_NAME: &str = "sensor_msgs/msg/JointState";

/// Schema name of `/robot_description`.
pub const STRING_NAME: &str = "std_msgs/msg/String";

/// `ros2msg` schema data of `sensor_msgs/msg/JointState`: its definition, then each dependency after
/// a line of 80 `=` and a line `MSG: pkg/Type` (MCAP format registry, "ros2msg Data Format").
pub const JOINT_STATE_DEFINITION: &str = "\
std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// `ros2msg` schema data of `std_msgs/msg/String` (no dependencies).
pub const STRING_DEFINITION: &str = "string data\n";

/// `builtin_interfaces/Time`.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, `0..1_000_000_000`.
    pub nanosec: u32,
}

impl Time {
    /// Splits nanoseconds from 0; `None` past `i32::MAX` seconds.
    pub fn from_nanos(nanos: u64) -> Option<Self> {
        const NANOS_PER_SECOND: u64 = 1_000_000_000;
        Some(Self {
            sec: i32::try_from(nanos / NANOS_PER_SECOND).ok()?,
            nanosec: u32::try_from(nanos % NANOS_PER_SECOND).ok()?,
        })
    }
}

/// `std_msgs/Header`.
#[derive(Clone, Debug, Serialize)]
pub struct Header<'a> {
    /// Time stamp.
    pub stamp: Time,
    /// Frame (empty: the values are not spatial).
    pub frame_id: &'a str,
}

/// `sensor_msgs/msg/JointState` with the values in `position` and empty velocity and effort.
#[derive(Clone, Debug, Serialize)]
pub struct JointState<'a> {
    /// Header.
    pub header: Header<'a>,
    /// Series names (`lower`, `nominal`, `upper`, or `estimate`).
    pub name: &'a [&'a str],
    /// Values, one per name.
    pub position: &'a [f64],
    /// Empty.
    pub velocity: &'a [f64],
    /// Empty.
    pub effort: &'a [f64],
}

/// `std_msgs/msg/String`.
#[derive(Clone, Debug, Serialize)]
pub struct RosString<'a> {
    /// The text.
    pub data: &'a str,
}

/// Serializes `message` as a CDR little-endian payload, encapsulation header included (what the
/// MCAP `cdr` message encoding holds).
pub fn encode<T: Serialize>(message: &T) -> Result<Vec<u8>, cdr::Error> {
    cdr::serialize::<_, _, cdr::CdrLe>(message, cdr::Infinite)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joint_state_bytes_follow_cdr_alignment() {
        let names = ["estimate"];
        let values = [0.5];
        let bytes = encode(&JointState {
            header: Header {
                stamp: Time { sec: 1, nanosec: 2 },
                frame_id: "",
            },
            name: &names,
            position: &values,
            velocity: &[],
            effort: &[],
        })
        .unwrap();
        let mut expected = vec![0, 1, 0, 0]; // CDR_LE encapsulation
        expected.extend(1_i32.to_le_bytes()); // sec
        expected.extend(2_u32.to_le_bytes()); // nanosec
        expected.extend(1_u32.to_le_bytes()); // frame_id: length 1 (the NUL)
        expected.push(0);
        expected.extend([0, 0, 0]); // pad to 4
        expected.extend(1_u32.to_le_bytes()); // one name
        expected.extend(9_u32.to_le_bytes());
        expected.extend(b"estimate\0");
        expected.extend([0, 0, 0]); // pad to 4
        expected.extend(1_u32.to_le_bytes()); // one position
        expected.extend(0.5_f64.to_le_bytes()); // already 8-aligned (offset 40 after the header)
        expected.extend(0_u32.to_le_bytes()); // no velocity
        expected.extend(0_u32.to_le_bytes()); // no effort
        assert_eq!(bytes, expected);
    }

    #[test]
    fn time_splits_nanoseconds() {
        let t = Time::from_nanos(2_500_000_001).unwrap();
        assert_eq!((t.sec, t.nanosec), (2, 500_000_001));
        assert!(Time::from_nanos(u64::MAX).is_none());
    }
}
