//! The geometric conventions of the loaded types: camera frames and rays, rotations,
//! gobo bases.

use crate::common::*;
use glam::{Mat3, Vec3};
use nimbus_scene::*;

fn assert_close(a: Vec3, b: Vec3) {
    assert!((a - b).length() < 1e-5, "{a} != {b}");
}

#[test]
fn frame_at_interpolates_keyframes_and_clamps_outside() {
    let scene = parse(
        r#"
[render]
frames = 20
[camera]
[[camera.keyframe]]
frame = 12
position = [10, 0, 0]
look_at = [10, 0, -10]
[[camera.keyframe]]
frame = 2
position = [0, 0, 0]
look_at = [0, 0, -10]
"#,
    )
    .unwrap();
    let camera = &scene.camera;
    assert_close(camera.frame_at(0).position, Vec3::ZERO);
    assert_close(camera.frame_at(2).position, Vec3::ZERO);
    assert_close(camera.frame_at(7).position, Vec3::new(5.0, 0.0, 0.0));
    assert_close(camera.pose_at(7).1, Vec3::new(5.0, 0.0, -10.0));
    assert_close(camera.frame_at(12).position, Vec3::new(10.0, 0.0, 0.0));
    assert_close(camera.frame_at(100).position, Vec3::new(10.0, 0.0, 0.0));
    assert_close(camera.frame_at(7).forward, Vec3::NEG_Z);

    let still = parse(CAMERA).unwrap().camera;
    assert_eq!(still.frame_at(0), still.frame_at(1000));
    assert_close(still.frame_at(3).position, Vec3::new(0.0, 0.0, 5.0));
}

#[test]
fn camera_frame_is_orthonormal_with_right_from_forward_cross_up() {
    let camera = parse("[camera]\nposition = [1, 2, 3]\nlook_at = [-2, 0, 1]\nup = [0.1, 3, 0]\nhorizontal_fov_deg = 90\n")
        .unwrap()
        .camera;
    let frame = camera.frame_at(0);
    assert_close(frame.forward, (Vec3::new(-3.0, -2.0, -2.0)).normalize());
    assert_close(frame.right, frame.forward.cross(camera.up).normalize());
    assert_close(frame.up, frame.right.cross(frame.forward));
    for v in [frame.forward, frame.right, frame.up] {
        assert!((v.length() - 1.0).abs() < 1e-5);
    }
    assert!(
        frame.up.dot(camera.up) > 0.0,
        "image up points along the scene's up"
    );
    assert!((frame.tan_half_fov_x - 1.0).abs() < 1e-6);
}

#[test]
fn ray_direction_has_pixel_zero_at_the_top_left() {
    let camera = parse(&format!("{CAMERA}horizontal_fov_deg = 90\n"))
        .unwrap()
        .camera;
    let frame = camera.frame_at(0);
    assert_close(frame.right, Vec3::X);
    assert_close(frame.up, Vec3::Y);
    let (width, height) = (200, 100);

    let top_left = frame.ray_direction(0.0, 0.0, width, height);
    assert!(top_left.dot(frame.up) > 0.0);
    assert!(top_left.dot(frame.right) < 0.0);
    assert!((top_left.length() - 1.0).abs() < 1e-6);

    let bottom_right = frame.ray_direction(width as f32, height as f32, width, height);
    assert!(bottom_right.dot(frame.up) < 0.0);
    assert!(bottom_right.dot(frame.right) > 0.0);

    assert_close(
        frame.ray_direction(100.0, 50.0, width, height),
        frame.forward,
    );
    // The full horizontal field of view spans the image width: 45° each side.
    assert_close(
        frame.ray_direction(200.0, 50.0, width, height),
        (frame.forward + frame.right).normalize(),
    );
    // Square pixels: the vertical extent follows the aspect ratio (tan = 0.5 here).
    assert_close(
        frame.ray_direction(100.0, 0.0, width, height),
        (frame.forward + 0.5 * frame.up).normalize(),
    );
}

#[test]
fn rotation_is_about_x_then_y_then_z() {
    assert_close(
        rotation_xyz_deg(Vec3::new(0.0, 0.0, 90.0)) * Vec3::X,
        Vec3::Y,
    );
    assert_close(
        rotation_xyz_deg(Vec3::new(90.0, 0.0, 0.0)) * Vec3::Y,
        Vec3::Z,
    );
    assert_close(
        rotation_xyz_deg(Vec3::new(0.0, 90.0, 0.0)) * Vec3::Z,
        Vec3::X,
    );
    // X first takes Y to Z, then Y takes Z to X (the other order would give Z).
    assert_close(
        rotation_xyz_deg(Vec3::new(90.0, 90.0, 0.0)) * Vec3::Y,
        Vec3::X,
    );

    let angles = Vec3::new(30.0, -50.0, 110.0);
    let v = Vec3::new(0.3, -1.2, 2.0);
    let about = |axis: usize| {
        let mut single = Vec3::ZERO;
        single[axis] = angles[axis];
        rotation_xyz_deg(single)
    };
    let sequential = about(2) * (about(1) * (about(0) * v));
    assert_close(rotation_xyz_deg(angles) * v, sequential);
    let rotation = rotation_xyz_deg(angles);
    assert!((rotation * rotation.transpose()).abs_diff_eq(Mat3::IDENTITY, 1e-6));
}

#[test]
fn gobo_basis_is_orthonormal_and_perpendicular_to_the_beam() {
    let directions = [
        Vec3::NEG_Y,
        Vec3::Y,
        Vec3::X,
        Vec3::new(0.3, -1.0, 0.2),
        Vec3::new(0.001, -1.0, 0.0),
        Vec3::new(-2.0, -0.1, 5.0),
    ];
    for d in directions {
        let d = d.normalize();
        let (u, v) = Gobo::basis(d);
        for (a, b, expected) in [
            (u, u, 1.0),
            (v, v, 1.0),
            (u, v, 0.0),
            (u, d, 0.0),
            (v, d, 0.0),
        ] {
            assert!((a.dot(b) - expected).abs() < 1e-5, "basis of {d}: {u}, {v}");
        }
        // (u, v, -d) is right-handed, like the camera's (right, up, -forward).
        assert_close(u.cross(v), -d);
    }
    let (u, v) = Gobo::basis(Vec3::NEG_Y);
    assert_close(u, Vec3::X);
    assert_close(v, Vec3::NEG_Z);
}
