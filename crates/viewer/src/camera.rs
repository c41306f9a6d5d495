//! Orbit / pan / zoom camera for the viewport.
//!
//! The camera orbits a pivot at a distance; +y stays up, the same convention as
//! [`nusselt_core::scene::Camera`] (image right = forward × up), so the viewer opens on exactly the
//! scene's own view (for the Cornell box the published one) and picking rays use
//! [`nusselt_core::scene::Camera::ray_dir`].

use glam::{DMat4, DVec3, DVec4, Mat4};

use nusselt_core::scene::Camera;

/// Largest pitch, short of straight up or down where "up" is undefined.
const MAX_PITCH: f64 = 89.0_f64 * std::f64::consts::PI / 180.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    pub pivot: DVec3,
    pub distance: f64,
    /// Radians; 0 looks along +z.
    pub yaw: f64,
    /// Radians; positive looks up.
    pub pitch: f64,
    pub vfov_deg: f64,
    /// Size of the scene, for clip planes and speeds.
    pub scene_radius: f64,
}

impl OrbitCamera {
    /// The same view as `camera`, orbiting the point in front of it at the depth of the
    /// scene's centre.
    pub fn from_camera(camera: &Camera, bounds_min: DVec3, bounds_max: DVec3) -> OrbitCamera {
        let center = (bounds_min + bounds_max) * 0.5;
        let radius = ((bounds_max - bounds_min).length() * 0.5).max(1e-9);
        let forward = (camera.target - camera.eye)
            .try_normalize()
            .unwrap_or(DVec3::Z);
        let depth = (center - camera.eye).dot(forward).max(radius * 0.05);
        OrbitCamera {
            pivot: camera.eye + forward * depth,
            distance: depth,
            yaw: forward.x.atan2(forward.z),
            pitch: forward
                .y
                .clamp(-1.0, 1.0)
                .asin()
                .clamp(-MAX_PITCH, MAX_PITCH),
            vfov_deg: camera.vfov_deg,
            scene_radius: radius,
        }
    }

    pub fn forward(&self) -> DVec3 {
        DVec3::new(
            self.pitch.cos() * self.yaw.sin(),
            self.pitch.sin(),
            self.pitch.cos() * self.yaw.cos(),
        )
    }

    pub fn eye(&self) -> DVec3 {
        self.pivot - self.forward() * self.distance
    }

    /// As a scene camera (for picking rays and for comparing with `nusselt render`).
    pub fn to_camera(&self) -> Camera {
        Camera {
            eye: self.eye(),
            target: self.pivot,
            vfov_deg: self.vfov_deg,
        }
    }

    /// Turns around the pivot by a drag of (dx, dy) points.
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        let speed = 0.006;
        self.yaw -= dx * speed;
        self.pitch = (self.pitch + dy * speed).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Moves the pivot in the view plane so the point under the cursor follows a drag of
    /// (dx, dy) points in a viewport `height` points tall.
    pub fn pan(&mut self, dx: f64, dy: f64, height: f64) {
        let Some((_, right, up)) = self.to_camera().basis() else {
            return;
        };
        let per_point =
            2.0 * self.distance * (self.vfov_deg.to_radians() * 0.5).tan() / height.max(1.0);
        self.pivot += (-right * dx + up * dy) * per_point;
    }

    /// Moves toward (positive `amount`) or away from the pivot.
    pub fn zoom(&mut self, amount: f64) {
        let d = self.distance * (-amount * 0.002).exp();
        self.distance = d.clamp(self.scene_radius * 1e-3, self.scene_radius * 100.0);
    }

    /// Keeps the direction, centres the pivot on the box and backs off until it fits.
    pub fn frame(&mut self, bounds_min: DVec3, bounds_max: DVec3, aspect: f64) {
        let center = (bounds_min + bounds_max) * 0.5;
        let radius = ((bounds_max - bounds_min).length() * 0.5).max(1e-9);
        let half_v = self.vfov_deg.to_radians() * 0.5;
        let half_h = (half_v.tan() * aspect.max(1e-3)).atan();
        let half = half_v.min(half_h);
        self.pivot = center;
        self.scene_radius = radius;
        self.distance = radius / half.sin();
    }

    /// Clip-space matrix (wgpu depth range 0..1).
    pub fn view_proj(&self, aspect: f64) -> Mat4 {
        let eye = self.eye();
        let near = (self.distance - 2.0 * self.scene_radius).max(self.scene_radius * 1e-3);
        let far = self.distance + 2.0 * self.scene_radius;
        let Some((f, s, u)) = self.to_camera().basis() else {
            return Mat4::IDENTITY;
        };
        // Right-handed look-at (camera looks down −z) and a perspective onto wgpu's 0..1
        // depth range.
        let view = DMat4::from_cols(
            DVec4::new(s.x, u.x, -f.x, 0.0),
            DVec4::new(s.y, u.y, -f.y, 0.0),
            DVec4::new(s.z, u.z, -f.z, 0.0),
            DVec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
        );
        let h = 1.0 / (self.vfov_deg.to_radians() * 0.5).tan();
        let w = h / aspect.max(1e-6);
        let r = far / (near - far);
        let proj = DMat4::from_cols(
            DVec4::new(w, 0.0, 0.0, 0.0),
            DVec4::new(0.0, h, 0.0, 0.0),
            DVec4::new(0.0, 0.0, r, -1.0),
            DVec4::new(0.0, 0.0, r * near, 0.0),
        );
        (proj * view).as_mat4()
    }

    /// A ray through a point of the viewport, (x, y) in points from its top-left corner.
    pub fn ray(&self, x: f64, y: f64, width: f64, height: f64) -> (DVec3, DVec3) {
        let cam = self.to_camera();
        // `ray_dir` takes pixels; any unit works as long as size and position agree.
        let scale = 1024.0;
        let dir = cam.ray_dir(
            x * scale,
            y * scale,
            (width * scale).max(1.0) as u32,
            (height * scale).max(1.0) as u32,
        );
        (cam.eye, dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cornell_view_is_kept() {
        let cam = Camera::cornell();
        let o = OrbitCamera::from_camera(&cam, DVec3::ZERO, DVec3::new(556.0, 548.8, 559.2));
        assert!((o.eye() - cam.eye).length() < 1e-9, "{:?}", o.eye());
        let f = o.forward();
        assert!((f - DVec3::Z).length() < 1e-12);
        assert!((o.vfov_deg - 39.3077).abs() < 1e-4);
    }

    #[test]
    fn projection_puts_the_pivot_in_the_middle_and_left_is_plus_x() {
        let o = OrbitCamera::from_camera(
            &Camera::cornell(),
            DVec3::ZERO,
            DVec3::new(556.0, 548.8, 559.2),
        );
        let m = o.view_proj(1.0);
        let p = m.project_point3(o.pivot.as_vec3());
        assert!(p.x.abs() < 1e-5 && p.y.abs() < 1e-5 && p.z > 0.0 && p.z < 1.0);
        // Looking along +z with +y up, the image's left is +x (the red wall's side).
        let left = m.project_point3((o.pivot + DVec3::X * 100.0).as_vec3());
        assert!(left.x < 0.0);
        // A ray through the centre goes through the pivot.
        let (eye, dir) = o.ray(50.0, 50.0, 100.0, 100.0);
        let d = dir.try_normalize().expect("dir");
        assert!((d - DVec3::Z).length() < 1e-9);
        assert!((eye - o.eye()).length() < 1e-9);
    }

    #[test]
    fn orbit_pan_zoom_stay_finite_and_frame_fits() {
        let mut o = OrbitCamera::from_camera(&Camera::cornell(), DVec3::ZERO, DVec3::ONE);
        for _ in 0..1000 {
            o.orbit(37.0, 91.0);
            o.pan(5.0, -3.0, 0.0);
            o.zoom(1e6);
        }
        assert!(o.eye().is_finite() && o.pitch.abs() <= MAX_PITCH);
        o.frame(DVec3::ZERO, DVec3::ONE, 2.0);
        let m = o.view_proj(2.0);
        for c in 0..8 {
            let p = DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64);
            let q = m.project_point3(p.as_vec3());
            assert!(q.x.abs() <= 1.0 && q.y.abs() <= 1.0 && (0.0..=1.0).contains(&q.z));
        }
    }
}
