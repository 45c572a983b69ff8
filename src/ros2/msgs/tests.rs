//! Byte-exact checks: each expected vector spells out the header, every field and every padding
//! byte by hand (offsets counted from the end of the 4-byte encapsulation header).

use super::*;

fn f64s(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

const HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
const STAMP: Stamp = Stamp { sec: 1, nanosec: 2 };

#[test]
fn type_hashes_are_jazzys() {
    // Sources: Jazzy's generated headers (`geometry_msgs/msg/detail/pose_stamped__struct.h`,
    // `nav_msgs/msg/detail/{odometry,path,occupancy_grid}__struct.h`,
    // `tf2_msgs/msg/detail/tf_message__struct.h`, as micro-ROS/micro_ros_arduino ships them),
    // agreeing with `ros2 topic info -v` outputs and a Jazzy rosbag2 metadata.yaml (TFMessage).
    assert_eq!(
        POSE_STAMPED.hash,
        "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"
    );
    assert_eq!(
        ODOMETRY.hash,
        "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0"
    );
    assert_eq!(
        PATH.hash,
        "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b"
    );
    assert_eq!(
        TF_MESSAGE.hash,
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
    );
    assert_eq!(
        OCCUPANCY_GRID.hash,
        "RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7"
    );
    for t in [POSE_STAMPED, ODOMETRY, PATH, TF_MESSAGE, OCCUPANCY_GRID] {
        let (pkg, name) = t.ros_name.split_once("/msg/").unwrap();
        assert_eq!(t.dds_name, format!("{pkg}::msg::dds_::{name}_"));
    }
}

#[test]
fn pose_stamped_bytes() {
    let p = Pose {
        position_m: [1.0, 2.0, 3.0],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
    };
    let bytes = pose_stamped(STAMP, "map", &p);
    #[rustfmt::skip]
    let expected: Vec<u8> = [
        &HEADER[..],
        &[1, 0, 0, 0],           // 0: stamp.sec
        &[2, 0, 0, 0],           // 4: stamp.nanosec
        &[4, 0, 0, 0],           // 8: frame_id length, NUL counted
        b"map\0",                // 12
        &f64s(&[1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]), // 16: already 8-aligned
    ]
    .concat();
    assert_eq!(bytes, expected);
    assert_eq!(bytes.len(), 76);
    let back = decode_pose_stamped(&bytes).unwrap();
    assert_eq!(back.frame_id, "map");
    assert_eq!(back.pose, p);
    assert_eq!(back.stamp, STAMP);
}

#[test]
fn odometry_bytes() {
    let p = Pose::from_yaw([1.0, 2.0, 3.0], 0.0);
    let bytes = odometry(STAMP, "world", "base", &p, [0.5, 0.0, -0.25]);
    let mut expected: Vec<u8> = [
        &HEADER[..],
        &[1, 0, 0, 0, 2, 0, 0, 0],
        &[6, 0, 0, 0],
        b"world\0", // 12..18
        &[0, 0],    // 18: pad to 20
        &[5, 0, 0, 0],
        b"base\0",  // 24..29
        &[0, 0, 0], // 29: pad to 32
        &f64s(&[1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]),
    ]
    .concat();
    expected.extend(f64s(&[0.0; 36]));
    expected.extend(f64s(&[0.5, 0.0, -0.25, 0.0, 0.0, 0.0]));
    expected.extend(f64s(&[0.0; 36]));
    assert_eq!(bytes, expected);
    assert_eq!(bytes.len(), 4 + 712);
}

#[test]
fn path_bytes() {
    let bytes = path(STAMP, "map", &[[1.0, 2.0, 3.0]]);
    let expected: Vec<u8> = [
        &HEADER[..],
        &[1, 0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0],
        b"map\0",                              // 12..16
        &[1, 0, 0, 0],                         // 16: one pose
        &[1, 0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0], // 20: its header
        b"map\0",                              // 32..36
        &[0, 0, 0, 0],                         // 36: pad to 40
        &f64s(&[1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]),
    ]
    .concat();
    assert_eq!(bytes, expected);
}

#[test]
fn tf_message_bytes() {
    let t = Transform {
        parent: "world",
        child: "d/base_link",
        pose: Pose::from_yaw([1.0, 0.0, 2.0], std::f64::consts::PI),
    };
    let bytes = tf_message(STAMP, &[t]);
    let (s, c) = (std::f64::consts::FRAC_PI_2).sin_cos();
    let expected: Vec<u8> = [
        &HEADER[..],
        &[1, 0, 0, 0], // 0: one transform
        &[1, 0, 0, 0, 2, 0, 0, 0, 6, 0, 0, 0],
        b"world\0", // 16..22
        &[0, 0],    // 22: pad to 24
        &[12, 0, 0, 0],
        b"d/base_link\0", // 28..40: 8-aligned already
        &f64s(&[1.0, 0.0, 2.0, 0.0, 0.0, s, c]),
    ]
    .concat();
    assert_eq!(bytes, expected);
}

#[test]
fn occupancy_grid_bytes() {
    let info = GridInfo {
        resolution_m: 0.5,
        width_cells: 2,
        height_cells: 1,
        origin_m: [-1.0, -2.0],
    };
    let bytes = occupancy_grid(STAMP, "map", &info, &[-1, 100]);
    let expected: Vec<u8> = [
        &HEADER[..],
        &[1, 0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0],
        b"map\0",                  // 12..16
        &[1, 0, 0, 0, 2, 0, 0, 0], // 16: map_load_time
        &0.5f32.to_le_bytes(),     // 24: resolution
        &[2, 0, 0, 0, 1, 0, 0, 0], // 28: width, height
        &[0, 0, 0, 0],             // 36: pad to 40
        &f64s(&[-1.0, -2.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
        &[2, 0, 0, 0], // 96: data length
        &[0xff, 100],
    ]
    .concat();
    assert_eq!(bytes, expected);
}

#[test]
fn a_goal_of_another_type_or_cut_short_is_refused() {
    let p = Pose::from_yaw([1.0, 2.0, 3.0], 0.5);
    let good = pose_stamped(STAMP, "map", &p);
    assert!((decode_pose_stamped(&good).unwrap().pose.yaw_rad().unwrap() - 0.5).abs() < 1e-12);
    assert!(decode_pose_stamped(&good[..good.len() - 1]).is_err());
    let odom = odometry(STAMP, "map", "b", &p, [0.0; 3]);
    assert!(decode_pose_stamped(&odom).is_err());
    let mut bad_q = p;
    bad_q.orientation_xyzw = [0.0; 4];
    assert_eq!(bad_q.yaw_rad(), None);
}

#[test]
fn stamps_split_unix_nanoseconds() {
    assert_eq!(
        Stamp::from_unix_ns(1_700_000_000_123_456_789),
        Stamp {
            sec: 1_700_000_000,
            nanosec: 123_456_789
        }
    );
}

/// The bytes another CDR implementation writes for the same messages: rosbags 0.11.9's Jazzy
/// type store (`get_typestore(Stores.ROS2_JAZZY).serialize_cdr`), which also computes the type
/// hashes above from the type descriptions (`hash_rihs01`) and gets the same five.
#[test]
fn rosbags_writes_the_same_bytes() {
    let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<String>();
    assert_eq!(
        hex(&pose_stamped(
            STAMP,
            "map",
            &Pose::from_yaw([1.0, 2.0, 3.0], 0.0)
        )),
        concat!(
            "000100000100000002000000040000006d617000000000000000f03f00000000",
            "0000004000000000000008400000000000000000000000000000000000000000",
            "00000000000000000000f03f",
        ),
        "pose"
    );
    assert_eq!(
        hex(&odometry(
            STAMP,
            "world",
            "base",
            &Pose::from_yaw([1.0, 2.0, 3.0], 0.0),
            [0.5, 0.0, -0.25]
        )),
        concat!(
            "00010000010000000200000006000000776f726c640000000500000062617365",
            "00000000000000000000f03f0000000000000040000000000000084000000000",
            "0000000000000000000000000000000000000000000000000000f03f00000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000e03f0000000000000000000000000000d0bf000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "000000000000000000000000",
        ),
        "odom"
    );
    assert_eq!(
        hex(&path(STAMP, "map", &[[1.0, 2.0, 3.0]])),
        concat!(
            "000100000100000002000000040000006d617000010000000100000002000000",
            "040000006d61700000000000000000000000f03f000000000000004000000000",
            "0000084000000000000000000000000000000000000000000000000000000000",
            "0000f03f",
        ),
        "path"
    );
    assert_eq!(
        hex(&tf_message(
            STAMP,
            &[Transform {
                parent: "world",
                child: "d/base_link",
                pose: Pose::from_yaw([1.0, 0.0, 2.0], std::f64::consts::PI)
            }]
        )),
        concat!(
            "0001000001000000010000000200000006000000776f726c640000000c000000",
            "642f626173655f6c696e6b00000000000000f03f000000000000000000000000",
            "0000004000000000000000000000000000000000000000000000f03f075c1433",
            "26a6913c",
        ),
        "tf"
    );
    assert_eq!(
        hex(&occupancy_grid(
            STAMP,
            "map",
            &GridInfo {
                resolution_m: 0.5,
                width_cells: 2,
                height_cells: 1,
                origin_m: [-1.0, -2.0]
            },
            &[-1, 100]
        )),
        concat!(
            "000100000100000002000000040000006d61700001000000020000000000003f",
            "020000000100000000000000000000000000f0bf00000000000000c000000000",
            "0000000000000000000000000000000000000000000000000000000000000000",
            "0000f03f02000000ff64",
        ),
        "grid"
    );
}
