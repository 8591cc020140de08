//! Camera rays in f64.

use glam::DVec3;
use nimbus_scene::Scene;

/// Camera rays of frame 0 in f64, with `CameraFrame::ray_direction`'s convention.
pub(crate) struct CameraRays {
    pub(crate) position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_x: f64,
    tan_y: f64,
    width: f64,
    height: f64,
}

impl CameraRays {
    pub(crate) fn new(scene: &Scene) -> Self {
        let (position, look_at) = scene.camera.pose_at(0);
        let (position, look_at) = (position.as_dvec3(), look_at.as_dvec3());
        let forward = (look_at - position).normalize();
        let right = forward.cross(scene.camera.up.as_dvec3()).normalize();
        let up = right.cross(forward);
        let (width, height) = (
            f64::from(scene.render.width),
            f64::from(scene.render.height),
        );
        let tan_x = (f64::from(scene.camera.horizontal_fov_deg).to_radians() * 0.5).tan();
        Self {
            position,
            forward,
            right,
            up,
            tan_x,
            tan_y: tan_x * height / width,
            width,
            height,
        }
    }

    /// Unit direction through image-plane point (px, py) in pixels, (0, 0) the top left.
    pub(crate) fn direction(&self, px: f64, py: f64) -> DVec3 {
        let sx = (2.0 * px / self.width - 1.0) * self.tan_x;
        let sy = (1.0 - 2.0 * py / self.height) * self.tan_y;
        (self.forward + sx * self.right + sy * self.up).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::common::testing::test_scene;

    #[test]
    fn camera_rays_match_the_scene_convention() {
        let s = test_scene(Vec::new(), Vec::new(), Vec::new(), (6, 4), 40.0);
        let (camera, frame) = (CameraRays::new(&s), s.camera.frame_at(0));
        for (px, py) in [(0.0, 0.0), (2.5, 1.25), (6.0, 4.0)] {
            let expected = frame.ray_direction(px as f32, py as f32, 6, 4).as_dvec3();
            assert!(camera.direction(px, py).abs_diff_eq(expected, 1e-6));
        }
    }
}
