//! Light sources that are not faces of the model: a uniform sky, suns and point lights.
//!
//! Units are radiometric, as for `Ke`: a sky is a radiance (W m⁻² sr⁻¹) arriving from every
//! direction in which a ray leaves the model; a sun is the irradiance (W m⁻²) it gives a
//! surface facing it; a point light is an intensity (W sr⁻¹). A rectangular area light is an
//! emitting face ([`super::Scene::add_area_light`]), the same as an emitting face of a file.
//!
//! What a receiver gets, as the irradiance over π that the solver and renderers multiply by
//! ρ (the units of [`crate::render::direct::DirectLight::incident`]):
//! - sky: `L · f`, with `f` the cosine-weighted fraction of the hemisphere through which a
//!   ray escapes (1 on an unoccluded plane facing up: `H = π L`; 0 inside a closed box);
//! - sun: `E · max(0, n·s) · V / π`, `s` the unit direction *towards* the sun, `V` its
//!   visibility (a cone of `angular_radius` for a soft shadow, one direction for a hard one);
//! - point: `I · max(0, n·w) · V / (π r²)`, inverse-square; a spot light (a point light with
//!   a [`SpotCone`]) multiplies that by its cone's falloff.

use glam::DVec3;

use super::Rgb;

/// One light source that is not a face of the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Uniform radiance from every direction in which a ray leaves the model.
    Sky { radiance: Rgb },
    /// A directional light arriving from `direction` (unit, pointing towards the sun).
    Sun {
        direction: DVec3,
        irradiance: Rgb,
        /// Half-angle of the sun's disc in radians (0: a hard shadow).
        angular_radius: f64,
    },
    /// A point light: isotropic, or a spot light when it has a `cone` (`intensity` is then
    /// the intensity on the cone's axis).
    Point {
        position: DVec3,
        intensity: Rgb,
        cone: Option<SpotCone>,
    },
}

/// A spot light's cone, as glTF's `KHR_lights_punctual` defines it: the full intensity within
/// `inner` radians of the axis `direction` (unit, the way the light shines), none beyond
/// `outer`, and between them the square of a ramp linear in the cosine of the angle (the
/// falloff the extension's specification gives).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotCone {
    pub direction: DVec3,
    pub inner: f64,
    pub outer: f64,
}

impl SpotCone {
    /// The fraction of the axis intensity sent along unit `w` (from the light outwards):
    /// `t²`, `t = clamp((w·d − cos outer) / max(10⁻³, cos inner − cos outer), 0, 1)`.
    pub fn falloff(&self, w: DVec3) -> f64 {
        let (ci, co) = (self.inner.cos(), self.outer.cos());
        let t = ((w.dot(self.direction) - co) / (ci - co).max(1e-3)).clamp(0.0, 1.0);
        t * t
    }
}

/// What `--sky`, `--sun` or `--point` was given that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{flag} {text}: {message}")]
pub struct LightError {
    pub flag: &'static str,
    pub text: String,
    pub message: String,
}

fn numbers(flag: &'static str, text: &str, counts: &[usize]) -> Result<Vec<f64>, LightError> {
    let err = |message: String| LightError {
        flag,
        text: text.to_string(),
        message,
    };
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| err("expected comma-separated numbers".into()))?;
    if !counts.contains(&v.len()) {
        let want: Vec<String> = counts.iter().map(|c| c.to_string()).collect();
        return Err(err(format!(
            "expected {} numbers, got {}",
            want.join(" or "),
            v.len()
        )));
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(err(format!("{x} is not a finite number")));
    }
    Ok(v)
}

fn colour(flag: &'static str, text: &str, v: &[f64]) -> Result<Rgb, LightError> {
    let c = Rgb::new(v[0], v[1], v[2]);
    if c.min_element() < 0.0 {
        return Err(LightError {
            flag,
            text: text.to_string(),
            message: "the colour must be non-negative".into(),
        });
    }
    Ok(c)
}

impl Light {
    /// `R,G,B`: a uniform sky of that radiance.
    pub fn parse_sky(text: &str) -> Result<Light, LightError> {
        let v = numbers("--sky", text, &[3])?;
        Ok(Light::Sky {
            radiance: colour("--sky", text, &v)?,
        })
    }

    /// `X,Y,Z,R,G,B[,ANGULAR_RADIUS_DEG]`: a sun in direction X,Y,Z of irradiance R,G,B.
    pub fn parse_sun(text: &str) -> Result<Light, LightError> {
        let flag = "--sun";
        let v = numbers(flag, text, &[6, 7])?;
        let direction = DVec3::new(v[0], v[1], v[2])
            .try_normalize()
            .ok_or_else(|| LightError {
                flag,
                text: text.to_string(),
                message: "the direction X,Y,Z must not be zero".into(),
            })?;
        let radius = v.get(6).copied().unwrap_or(0.0);
        if !(0.0..=45.0).contains(&radius) {
            return Err(LightError {
                flag,
                text: text.to_string(),
                message: format!("the angular radius must be in 0..=45 degrees, got {radius}"),
            });
        }
        Ok(Light::Sun {
            direction,
            irradiance: colour(flag, text, &v[3..6])?,
            angular_radius: radius.to_radians(),
        })
    }

    /// `X,Y,Z,R,G,B`: a point light at X,Y,Z of intensity R,G,B.
    pub fn parse_point(text: &str) -> Result<Light, LightError> {
        let v = numbers("--point", text, &[6])?;
        Ok(Light::Point {
            position: DVec3::new(v[0], v[1], v[2]),
            intensity: colour("--point", text, &v[3..6])?,
            cone: None,
        })
    }

    /// One line for messages and panels.
    pub fn describe(&self) -> String {
        let c = |c: Rgb| format!("{:.3},{:.3},{:.3}", c.x, c.y, c.z);
        match self {
            Light::Sky { radiance } => format!("sky of radiance {}", c(*radiance)),
            Light::Sun {
                direction,
                irradiance,
                angular_radius,
            } => format!(
                "sun from {:.3},{:.3},{:.3} of irradiance {} (radius {:.2}°)",
                direction.x,
                direction.y,
                direction.z,
                c(*irradiance),
                angular_radius.to_degrees()
            ),
            Light::Point {
                position,
                intensity,
                cone,
            } => {
                let spot = cone.map_or(String::new(), |k| {
                    format!(
                        " shining along {:.3},{:.3},{:.3} (cone {:.1}° to {:.1}°)",
                        k.direction.x,
                        k.direction.y,
                        k.direction.z,
                        k.inner.to_degrees(),
                        k.outer.to_degrees()
                    )
                });
                format!(
                    "{} at {:.3},{:.3},{:.3} of intensity {}{spot}",
                    if cone.is_some() {
                        "spot light"
                    } else {
                        "point light"
                    },
                    position.x,
                    position.y,
                    position.z,
                    c(*intensity)
                )
            }
        }
    }

    /// Whether the light gives any light.
    pub fn is_on(&self) -> bool {
        let c = match self {
            Light::Sky { radiance } => radiance,
            Light::Sun { irradiance, .. } => irradiance,
            Light::Point { intensity, .. } => intensity,
        };
        c.max_element() > 0.0
    }
}

/// `X,Y,Z,NX,NY,NZ,SIZE,R,G,B`: the corners of a square emitter of side SIZE centred at
/// X,Y,Z facing NX,NY,NZ, and its radiance R,G,B (for [`super::Scene::add_area_light`]).
pub fn parse_area(text: &str) -> Result<(Vec<DVec3>, Rgb), LightError> {
    let flag = "--area";
    let v = numbers(flag, text, &[10])?;
    let err = |message: &str| LightError {
        flag,
        text: text.to_string(),
        message: message.into(),
    };
    let n = DVec3::new(v[3], v[4], v[5])
        .try_normalize()
        .ok_or_else(|| err("the normal NX,NY,NZ must not be zero"))?;
    if v[6] <= 0.0 {
        return Err(err("the size must be positive"));
    }
    let corners = super::square_corners(DVec3::new(v[0], v[1], v[2]), n, v[6]);
    Ok((corners, colour(flag, text, &v[7..10])?))
}

/// Total sky radiance of `lights`.
pub fn sky_radiance(lights: &[Light]) -> Rgb {
    lights
        .iter()
        .map(|l| match l {
            Light::Sky { radiance } => *radiance,
            _ => Rgb::ZERO,
        })
        .sum()
}

/// Whether `lights` hold a sun or a point light.
pub fn has_punctual(lights: &[Light]) -> bool {
    lights
        .iter()
        .any(|l| matches!(l, Light::Sun { .. } | Light::Point { .. }) && l.is_on())
}

/// The suns and point lights of `lights` (what [`punctual_incident`] evaluates).
pub fn punctual(lights: &[Light]) -> Vec<Light> {
    lights
        .iter()
        .filter(|l| !matches!(l, Light::Sky { .. }))
        .copied()
        .collect()
}

/// A direction in the cone of half-angle `radius` about unit `axis`, uniform in solid angle.
pub fn cone_direction(axis: DVec3, radius: f64, u1: f64, u2: f64) -> DVec3 {
    if radius <= 0.0 {
        return axis;
    }
    let cos_t = 1.0 - u1 * (1.0 - radius.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let (t, b) = crate::geometry::sampling::basis(axis);
    t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + axis * cos_t
}

/// Irradiance over π at `x` (unit normal `n`) from the suns and point lights of `lights`.
/// `visible(dir, t_max)` is the fraction of light a shadow ray from `x` along unit `dir`
/// lets through before `t_max` (∞ for a sun): 0 blocked, 1 free, a window's transmittance
/// between; `u` are two uniforms for a soft sun's direction.
pub fn punctual_incident(
    lights: &[Light],
    x: DVec3,
    n: DVec3,
    u: (f64, f64),
    visible: &dyn Fn(DVec3, f64) -> f64,
) -> Rgb {
    let mut sum = Rgb::ZERO;
    for l in lights {
        match *l {
            Light::Sun {
                direction,
                irradiance,
                angular_radius,
            } => {
                let s = cone_direction(direction, angular_radius, u.0, u.1);
                let cos = n.dot(s);
                if cos > 0.0 && irradiance.max_element() > 0.0 {
                    sum += irradiance * (cos * visible(s, f64::INFINITY) / std::f64::consts::PI);
                }
            }
            Light::Point {
                position,
                intensity,
                cone,
            } => {
                let d = position - x;
                let r2 = d.length_squared();
                let Some(w) = d.try_normalize() else { continue };
                let cos = n.dot(w);
                let spot = cone.map_or(1.0, |k| k.falloff(-w));
                if cos > 0.0 && spot > 0.0 && intensity.max_element() > 0.0 {
                    sum += intensity
                        * (spot * cos * visible(w, r2.sqrt()) / (std::f64::consts::PI * r2));
                }
            }
            Light::Sky { .. } => {}
        }
    }
    debug_assert!(sum.is_finite());
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_parse_and_refuse_bad_values() {
        assert_eq!(
            Light::parse_sky("1,2,3").unwrap(),
            Light::Sky {
                radiance: Rgb::new(1.0, 2.0, 3.0)
            }
        );
        let Light::Sun { direction, .. } = Light::parse_sun("0,2,0,1,1,1").unwrap() else {
            panic!("not a sun");
        };
        assert_eq!(direction, DVec3::Y);
        for (bad, what) in [
            (Light::parse_sun("0,0,0,1,1,1"), "must not be zero"),
            (Light::parse_sun("0,1,0,1,-1,1"), "non-negative"),
            (Light::parse_sun("0,1,0,1,1"), "expected 6 or 7"),
            (Light::parse_point("0,1,0,1,1,inf"), "finite"),
            (Light::parse_sky("a,b,c"), "comma-separated"),
            (Light::parse_sun("0,1,0,1,1,1,90"), "angular radius"),
        ] {
            let e = bad.expect_err(what).to_string();
            assert!(e.contains(what), "{e}");
        }
    }

    #[test]
    fn sun_and_point_follow_the_cosine_and_inverse_square_laws() {
        let open = |_: DVec3, _: f64| 1.0;
        let sun = Light::Sun {
            direction: DVec3::new(0.0, 1.0, 1.0).normalize_or_zero(),
            irradiance: Rgb::splat(2.0),
            angular_radius: 0.0,
        };
        let h = punctual_incident(&[sun], DVec3::ZERO, DVec3::Y, (0.5, 0.5), &open);
        let want = 2.0 * std::f64::consts::FRAC_1_SQRT_2 / std::f64::consts::PI;
        assert!((h.x - want).abs() < 1e-12, "{h}");
        let point = Light::Point {
            position: DVec3::new(3.0, 4.0, 0.0),
            intensity: Rgb::splat(25.0),
            cone: None,
        };
        let h = punctual_incident(&[point], DVec3::ZERO, DVec3::Y, (0.5, 0.5), &open);
        // I cosθ / r² = 25 · 0.8 / 25.
        assert!((h.x - 0.8 / std::f64::consts::PI).abs() < 1e-12, "{h}");
        let shut = |_: DVec3, _: f64| 0.0;
        assert_eq!(
            punctual_incident(&[sun, point], DVec3::ZERO, DVec3::Y, (0.5, 0.5), &shut),
            Rgb::ZERO
        );
    }

    /// The KHR_lights_punctual falloff: 1 inside the inner cone, 0 outside the outer one, and
    /// at the cosine halfway between the two, (½)² = ¼.
    #[test]
    fn a_spot_light_falls_off_between_its_cones() {
        let open = |_: DVec3, _: f64| 1.0;
        let (inner, outer) = (0.2f64, 0.4f64);
        let spot = |pos: DVec3| Light::Point {
            position: pos,
            intensity: Rgb::splat(1.0),
            cone: Some(SpotCone {
                direction: DVec3::NEG_Y,
                inner,
                outer,
            }),
        };
        let at = |angle: f64| {
            // A receiver 1 below and `angle` off the axis, facing the light.
            let x = DVec3::new(angle.tan(), -1.0, 0.0);
            let n = (DVec3::ZERO - x).normalize_or_zero();
            punctual_incident(&[spot(DVec3::ZERO)], x, n, (0.5, 0.5), &open)
                * (std::f64::consts::PI * x.length_squared())
        };
        assert!((at(0.0).x - 1.0).abs() < 1e-12);
        assert!((at(0.19).x - 1.0).abs() < 1e-12);
        assert_eq!(at(0.41).x, 0.0);
        let half = (0.5 * (inner.cos() + outer.cos())).acos();
        assert!((at(half).x - 0.25).abs() < 1e-9, "{}", at(half));
        assert!(spot(DVec3::ZERO).describe().starts_with("spot light"));
    }

    #[test]
    fn an_area_flag_makes_a_square_facing_its_normal() {
        let (c, e) = parse_area("1,2,3,0,-1,0,2,5,5,5").unwrap();
        assert_eq!(e, Rgb::splat(5.0));
        let n = crate::geometry::polygon::normal(&c).unwrap();
        assert!((n - DVec3::NEG_Y).length() < 1e-12, "{n}");
        assert!((crate::geometry::polygon::area(&c) - 4.0).abs() < 1e-12);
        assert!(parse_area("0,0,0,0,0,0,1,1,1,1").is_err());
        assert!(parse_area("0,0,0,0,1,0,-1,1,1,1").is_err());
    }

    #[test]
    fn cone_directions_stay_in_the_cone() {
        let axis = DVec3::new(1.0, 2.0, 3.0).normalize_or_zero();
        let r = 5f64.to_radians();
        for k in 0..100 {
            let d = cone_direction(axis, r, k as f64 / 100.0, (k * 37 % 100) as f64 / 100.0);
            assert!((d.length() - 1.0).abs() < 1e-12);
            assert!(d.dot(axis) >= r.cos() - 1e-12);
        }
    }
}
