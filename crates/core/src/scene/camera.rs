//! Pinhole camera. Convention (see README "Units and conventions"): +y is up, the image's
//! right is `forward × up`, pixel (i, j) covers [i, i+1) × [j, j+1) with row 0 at the top.

use glam::DVec3;

use super::SceneError;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    /// Vertical field of view in degrees.
    pub vfov_deg: f64,
}

impl Camera {
    /// The published Cornell Box camera: eye (278, 273, −800), looking along +z,
    /// vertical field of view 2·atan(0.0125/0.035) = 39.3077°.
    pub fn cornell() -> Camera {
        Camera {
            eye: DVec3::new(278.0, 273.0, -800.0),
            target: DVec3::new(278.0, 273.0, 0.0),
            vfov_deg: 2.0 * (0.0125f64 / 0.035).atan().to_degrees(),
        }
    }

    /// Parses `ex,ey,ez,tx,ty,tz,vfov_deg`.
    pub fn parse(text: &str) -> Result<Camera, SceneError> {
        let bad = |why: &str| SceneError::Camera(format!("'{text}': {why}"));
        let v: Vec<f64> = text
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad("expected 7 comma-separated numbers ex,ey,ez,tx,ty,tz,vfov_deg"))?;
        if v.len() != 7 {
            return Err(bad(&format!("expected 7 numbers, found {}", v.len())));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(bad("numbers must be finite"));
        }
        let cam = Camera {
            eye: DVec3::new(v[0], v[1], v[2]),
            target: DVec3::new(v[3], v[4], v[5]),
            vfov_deg: v[6],
        };
        if !(v[6] > 0.0 && v[6] < 180.0) {
            return Err(bad("vfov_deg must be in (0, 180)"));
        }
        if cam.basis().is_none() {
            return Err(bad(
                "eye and target must differ and the view must not be straight up or down",
            ));
        }
        Ok(cam)
    }

    /// A view along −z that frames an axis-aligned box.
    pub fn framing(min: DVec3, max: DVec3) -> Camera {
        let center = (min + max) * 0.5;
        let radius = ((max - min).length() * 0.5).max(1e-9);
        let vfov_deg: f64 = 40.0;
        let dist = radius / (vfov_deg.to_radians() * 0.5).sin();
        Camera {
            eye: center + DVec3::new(0.0, 0.0, -dist),
            target: center,
            vfov_deg,
        }
    }

    /// (forward, right, up) unit vectors; `None` if degenerate.
    pub fn basis(&self) -> Option<(DVec3, DVec3, DVec3)> {
        let forward = (self.target - self.eye).try_normalize()?;
        let right = forward.cross(DVec3::Y).try_normalize()?;
        let up = right.cross(forward);
        Some((forward, right, up))
    }

    /// Direction (not normalised) through image position (x, y) in pixels, y down.
    pub fn ray_dir(&self, x: f64, y: f64, width: u32, height: u32) -> DVec3 {
        let (f, r, u) = self.basis().unwrap_or((DVec3::Z, DVec3::NEG_X, DVec3::Y));
        let tan = (self.vfov_deg.to_radians() * 0.5).tan();
        let aspect = width as f64 / height as f64;
        let sx = (2.0 * x / width as f64 - 1.0) * tan * aspect;
        let sy = (1.0 - 2.0 * y / height as f64) * tan;
        f + r * sx + u * sy
    }
}
