//! `foxglove.FrameTransforms` in protobuf: the message types (prost-derived, written after
//! Foxglove's `.proto` files) and the schema record's data, a `FileDescriptorSet` built here from
//! prost-derived descriptor types.
//!
//! The descriptor set must be byte-identical to the one Foxglove's own SDK writes (foxglove-sdk
//! 0.30; `tests/reference/check_mcap.py` compares the two), so it mirrors that file exactly: the
//! files in dependency order (Quaternion, Vector3, google/protobuf/timestamp, FrameTransform,
//! FrameTransforms), each field with name, number, label, type, type name and JSON name, and the
//! well-known Timestamp's file options. prost encodes fields in tag order, as protoc does.

/// `google.protobuf.Timestamp`.
#[derive(Clone, Copy, PartialEq, prost::Message)]
pub struct Timestamp {
    /// Whole seconds.
    #[prost(int64, tag = "1")]
    pub seconds: i64,
    /// Nanoseconds, `0..1_000_000_000`.
    #[prost(int32, tag = "2")]
    pub nanos: i32,
}

/// `foxglove.Vector3`.
#[derive(Clone, Copy, PartialEq, prost::Message)]
pub struct Vector3 {
    /// x.
    #[prost(double, tag = "1")]
    pub x: f64,
    /// y.
    #[prost(double, tag = "2")]
    pub y: f64,
    /// z.
    #[prost(double, tag = "3")]
    pub z: f64,
}

/// `foxglove.Quaternion`.
#[derive(Clone, Copy, PartialEq, prost::Message)]
pub struct Quaternion {
    /// x.
    #[prost(double, tag = "1")]
    pub x: f64,
    /// y.
    #[prost(double, tag = "2")]
    pub y: f64,
    /// z.
    #[prost(double, tag = "3")]
    pub z: f64,
    /// w.
    #[prost(double, tag = "4")]
    pub w: f64,
}

/// `foxglove.FrameTransform`: the pose of `child_frame_id` in `parent_frame_id`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct FrameTransform {
    /// Time stamp.
    #[prost(message, optional, tag = "1")]
    pub timestamp: Option<Timestamp>,
    /// Parent frame.
    #[prost(string, tag = "2")]
    pub parent_frame_id: String,
    /// Child frame.
    #[prost(string, tag = "3")]
    pub child_frame_id: String,
    /// The child origin in the parent frame.
    #[prost(message, optional, tag = "4")]
    pub translation: Option<Vector3>,
    /// The child orientation in the parent frame.
    #[prost(message, optional, tag = "5")]
    pub rotation: Option<Quaternion>,
}

/// `foxglove.FrameTransforms`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct FrameTransforms {
    /// The transforms.
    #[prost(message, repeated, tag = "1")]
    pub transforms: Vec<FrameTransform>,
}

/// Schema name of `/tf`.
pub const FRAME_TRANSFORMS_NAME: &str = "foxglove.FrameTransforms";

// The subset of google/protobuf/descriptor.proto (proto2: every scalar has explicit presence) that
// the descriptor set uses.

#[derive(Clone, PartialEq, prost::Message)]
struct FileDescriptorSet {
    #[prost(message, repeated, tag = "1")]
    file: Vec<FileDescriptorProto>,
}

#[derive(Clone, PartialEq, prost::Message)]
struct FileDescriptorProto {
    #[prost(string, optional, tag = "1")]
    name: Option<String>,
    #[prost(string, optional, tag = "2")]
    package: Option<String>,
    #[prost(string, repeated, tag = "3")]
    dependency: Vec<String>,
    #[prost(message, repeated, tag = "4")]
    message_type: Vec<DescriptorProto>,
    #[prost(message, optional, tag = "8")]
    options: Option<FileOptions>,
    #[prost(string, optional, tag = "12")]
    syntax: Option<String>,
}

#[derive(Clone, PartialEq, prost::Message)]
struct DescriptorProto {
    #[prost(string, optional, tag = "1")]
    name: Option<String>,
    #[prost(message, repeated, tag = "2")]
    field: Vec<FieldDescriptorProto>,
}

#[derive(Clone, PartialEq, prost::Message)]
struct FieldDescriptorProto {
    #[prost(string, optional, tag = "1")]
    name: Option<String>,
    #[prost(int32, optional, tag = "3")]
    number: Option<i32>,
    #[prost(int32, optional, tag = "4")]
    label: Option<i32>,
    #[prost(int32, optional, tag = "5")]
    r#type: Option<i32>,
    #[prost(string, optional, tag = "6")]
    type_name: Option<String>,
    #[prost(string, optional, tag = "10")]
    json_name: Option<String>,
}

#[derive(Clone, PartialEq, prost::Message)]
struct FileOptions {
    #[prost(string, optional, tag = "1")]
    java_package: Option<String>,
    #[prost(string, optional, tag = "8")]
    java_outer_classname: Option<String>,
    #[prost(bool, optional, tag = "10")]
    java_multiple_files: Option<bool>,
    #[prost(string, optional, tag = "11")]
    go_package: Option<String>,
    #[prost(bool, optional, tag = "31")]
    cc_enable_arenas: Option<bool>,
    #[prost(string, optional, tag = "36")]
    objc_class_prefix: Option<String>,
    #[prost(string, optional, tag = "37")]
    csharp_namespace: Option<String>,
}

/// `FieldDescriptorProto.Label.LABEL_OPTIONAL`.
const LABEL_OPTIONAL: i32 = 1;
/// `FieldDescriptorProto.Label.LABEL_REPEATED`.
const LABEL_REPEATED: i32 = 3;
/// `FieldDescriptorProto.Type.TYPE_DOUBLE`.
const TYPE_DOUBLE: i32 = 1;
/// `FieldDescriptorProto.Type.TYPE_INT64`.
const TYPE_INT64: i32 = 3;
/// `FieldDescriptorProto.Type.TYPE_INT32`.
const TYPE_INT32: i32 = 5;
/// `FieldDescriptorProto.Type.TYPE_STRING`.
const TYPE_STRING: i32 = 9;
/// `FieldDescriptorProto.Type.TYPE_MESSAGE`.
const TYPE_MESSAGE: i32 = 11;

/// A field; `json_name` is the lowerCamelCase of `name`, as protoc fills it in.
fn field(
    name: &str,
    number: i32,
    label: i32,
    r#type: i32,
    type_name: Option<&str>,
) -> FieldDescriptorProto {
    let mut json_name = String::with_capacity(name.len());
    let mut upper_next = false;
    for c in name.chars() {
        if c == '_' {
            upper_next = true;
        } else if upper_next {
            json_name.extend(c.to_uppercase());
            upper_next = false;
        } else {
            json_name.push(c);
        }
    }
    FieldDescriptorProto {
        name: Some(name.to_string()),
        number: Some(number),
        label: Some(label),
        r#type: Some(r#type),
        type_name: type_name.map(str::to_string),
        json_name: Some(json_name),
    }
}

/// A proto3 file with one message.
fn file(
    path: &str,
    package: &str,
    dependencies: &[&str],
    message: &str,
    fields: Vec<FieldDescriptorProto>,
    options: Option<FileOptions>,
) -> FileDescriptorProto {
    FileDescriptorProto {
        name: Some(path.to_string()),
        package: Some(package.to_string()),
        dependency: dependencies.iter().map(|d| d.to_string()).collect(),
        message_type: vec![DescriptorProto {
            name: Some(message.to_string()),
            field: fields,
        }],
        options,
        syntax: Some("proto3".to_string()),
    }
}

/// The schema data of `foxglove.FrameTransforms`: a serialized `FileDescriptorSet` holding it and
/// every file it depends on.
pub fn frame_transforms_descriptor_set() -> Vec<u8> {
    use prost::Message;
    let double = |name, number| field(name, number, LABEL_OPTIONAL, TYPE_DOUBLE, None);
    let quaternion = file(
        "foxglove/Quaternion.proto",
        "foxglove",
        &[],
        "Quaternion",
        vec![
            double("x", 1),
            double("y", 2),
            double("z", 3),
            double("w", 4),
        ],
        None,
    );
    let vector3 = file(
        "foxglove/Vector3.proto",
        "foxglove",
        &[],
        "Vector3",
        vec![double("x", 1), double("y", 2), double("z", 3)],
        None,
    );
    let timestamp = file(
        "google/protobuf/timestamp.proto",
        "google.protobuf",
        &[],
        "Timestamp",
        vec![
            field("seconds", 1, LABEL_OPTIONAL, TYPE_INT64, None),
            field("nanos", 2, LABEL_OPTIONAL, TYPE_INT32, None),
        ],
        Some(FileOptions {
            java_package: Some("com.google.protobuf".to_string()),
            java_outer_classname: Some("TimestampProto".to_string()),
            java_multiple_files: Some(true),
            go_package: Some("google.golang.org/protobuf/types/known/timestamppb".to_string()),
            cc_enable_arenas: Some(true),
            objc_class_prefix: Some("GPB".to_string()),
            csharp_namespace: Some("Google.Protobuf.WellKnownTypes".to_string()),
        }),
    );
    let frame_transform = file(
        "foxglove/FrameTransform.proto",
        "foxglove",
        &[
            "foxglove/Quaternion.proto",
            "foxglove/Vector3.proto",
            "google/protobuf/timestamp.proto",
        ],
        "FrameTransform",
        vec![
            field(
                "timestamp",
                1,
                LABEL_OPTIONAL,
                TYPE_MESSAGE,
                Some(".google.protobuf.Timestamp"),
            ),
            field("parent_frame_id", 2, LABEL_OPTIONAL, TYPE_STRING, None),
            field("child_frame_id", 3, LABEL_OPTIONAL, TYPE_STRING, None),
            field(
                "translation",
                4,
                LABEL_OPTIONAL,
                TYPE_MESSAGE,
                Some(".foxglove.Vector3"),
            ),
            field(
                "rotation",
                5,
                LABEL_OPTIONAL,
                TYPE_MESSAGE,
                Some(".foxglove.Quaternion"),
            ),
        ],
        None,
    );
    let frame_transforms = file(
        "foxglove/FrameTransforms.proto",
        "foxglove",
        &["foxglove/FrameTransform.proto"],
        "FrameTransforms",
        vec![field(
            "transforms",
            1,
            LABEL_REPEATED,
            TYPE_MESSAGE,
            Some(".foxglove.FrameTransform"),
        )],
        None,
    );
    FileDescriptorSet {
        file: vec![
            quaternion,
            vector3,
            timestamp,
            frame_transform,
            frame_transforms,
        ],
    }
    .encode_to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message;

    #[test]
    fn descriptor_set_round_trips_and_lists_the_files_in_dependency_order() {
        let bytes = frame_transforms_descriptor_set();
        let set = FileDescriptorSet::decode(bytes.as_slice()).unwrap();
        let names: Vec<_> = set.file.iter().map(|f| f.name.clone().unwrap()).collect();
        assert_eq!(
            names,
            [
                "foxglove/Quaternion.proto",
                "foxglove/Vector3.proto",
                "google/protobuf/timestamp.proto",
                "foxglove/FrameTransform.proto",
                "foxglove/FrameTransforms.proto"
            ]
        );
        assert_eq!(
            set.file[3].message_type[0].field[1].json_name.as_deref(),
            Some("parentFrameId")
        );
    }

    #[test]
    fn frame_transform_encodes_fields_in_tag_order() {
        let message = FrameTransforms {
            transforms: vec![FrameTransform {
                timestamp: Some(Timestamp {
                    seconds: 1,
                    nanos: 0,
                }),
                parent_frame_id: "world".to_string(),
                child_frame_id: "a".to_string(),
                translation: Some(Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                }),
                rotation: Some(Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 1.0,
                }),
            }],
        };
        let mut inner = vec![0x0a, 2, 0x08, 1]; // timestamp { seconds: 1 }
        inner.extend([0x12, 5]);
        inner.extend(b"world");
        inner.extend([0x1a, 1, b'a', 0x22, 0]); // child, empty translation
        inner.extend([0x2a, 9, 0x21]); // rotation { w: 1 }
        inner.extend(1.0_f64.to_le_bytes());
        let mut expected = vec![0x0a, inner.len() as u8];
        expected.extend(inner);
        assert_eq!(message.encode_to_vec(), expected);
    }
}
