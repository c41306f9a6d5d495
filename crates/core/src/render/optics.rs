//! Ideal specular optics: mirror reflection, Snell refraction and the Fresnel reflectance of
//! a smooth dielectric (unpolarised light, the mean of the s and p reflectances; Born & Wolf
//! §1.5; pbrt-v4 §9.3 `FrDielectric`). Shared by the path tracer and the hybrid eye pass.
//!
//! Exact for ideal smooth surfaces; no absorption inside the dielectric, no dispersion (one
//! index for all three channels), no polarisation carried between bounces (each bounce uses
//! the unpolarised mean, the usual renderer approximation: a few percent off after two
//! reflections near Brewster's angle).
//!
//! A glossy mirror is a mirror blurred by the Phong lobe (the glossy reflection of Cook,
//! Porter & Carpenter 1984, "Distributed ray tracing"): it reflects `Ks` of the light arriving
//! from directions spread around the mirror direction with density `(n + 1)/(2π) cosⁿα`, α
//! the angle to the mirror direction; the part of the lobe below the surface is lost. So it
//! reflects exactly `Ks` at normal incidence, a little less towards grazing (half at grazing
//! for a wide lobe), and tends to the perfect mirror as n grows, at every angle (the
//! normalized modified Phong BRDF of Lafortune & Willems 1994 tends to `Ks cos θ` instead,
//! dark at grazing: a jump at the exponent where a material becomes a mirror). Not
//! reciprocal (`f = Ks p(α)/cos θ`, θ of the sampled direction); only eye paths use it.

use glam::DVec3;

use crate::geometry::sampling::basis;

/// `d` reflected about the unit normal `n` (either side).
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// Fresnel reflectance of unpolarised light arriving with `cos_i` (> 0) to the normal on
/// the side of index `n1`, going into index `n2`. 1 beyond the critical angle (total
/// internal reflection).
pub fn fresnel_dielectric(cos_i: f64, n1: f64, n2: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// The refracted direction of unit `d` through a surface of unit normal `n` facing the
/// incoming side (`d·n` < 0), from index `n1` into `n2`; `None` under total internal
/// reflection.
pub fn refract(d: DVec3, n: DVec3, n1: f64, n2: f64) -> Option<DVec3> {
    let eta = n1 / n2;
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    (eta * d + (eta * cos_i - cos_t) * n).try_normalize()
}

/// What a ray does at a smooth dielectric of index `ior` hit with unit direction `d` on a
/// face of unit geometric normal `n` (pointing out of the dielectric), from the `front`
/// (outside) or not: the Fresnel reflectance, the reflected and the refracted direction
/// (`None` under total internal reflection) and the normal on the incoming side.
pub struct Interface {
    pub reflectance: f64,
    pub reflected: DVec3,
    pub refracted: Option<DVec3>,
    /// The normal facing the incoming ray (offset reflected rays along it, refracted ones
    /// against it).
    pub facing: DVec3,
}

pub fn dielectric(d: DVec3, n: DVec3, front: bool, ior: f64) -> Interface {
    let (n1, n2) = if front { (1.0, ior) } else { (ior, 1.0) };
    let facing = if d.dot(n) < 0.0 { n } else { -n };
    let cos_i = -d.dot(facing);
    let refracted = refract(d, facing, n1, n2);
    Interface {
        reflectance: if refracted.is_some() {
            fresnel_dielectric(cos_i, n1, n2)
        } else {
            1.0
        },
        reflected: reflect(d, facing),
        refracted,
        facing,
    }
}

/// A direction of the Phong lobe of `exponent` around the unit mirror direction `axis`,
/// drawn with density `(n + 1)/(2π) cosⁿα` from two uniforms; `None` when it falls below the
/// surface of unit `normal` (on the reflecting side): the lobe's lost part. A glossy mirror
/// shows `Ks` × the mean radiance along these directions, `None` counting zero.
pub fn phong_lobe(axis: DVec3, normal: DVec3, exponent: f64, u1: f64, u2: f64) -> Option<DVec3> {
    let cos_a = u1.powf(1.0 / (exponent + 1.0));
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let (t, b) = basis(axis);
    let dir = t * (sin_a * phi.cos()) + b * (sin_a * phi.sin()) + axis * cos_a;
    (dir.dot(normal) > 0.0).then_some(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At normal incidence the reflectance is ((n − 1)/(n + 1))², 0.04 for n = 1.5, from
    /// either side.
    #[test]
    fn normal_incidence_reflectance_is_the_textbook_value() {
        for n in [1.33f64, 1.5, 2.4] {
            let want = ((n - 1.0) / (n + 1.0)).powi(2);
            assert!((fresnel_dielectric(1.0, 1.0, n) - want).abs() < 1e-12);
            assert!((fresnel_dielectric(1.0, n, 1.0) - want).abs() < 1e-12);
        }
        assert!((fresnel_dielectric(1.0, 1.0, 1.5) - 0.04).abs() < 1e-12);
    }

    /// Energy: R + T = 1 with T computed independently from the Fresnel transmission
    /// amplitudes t_s = 2 n1 cos i / (n1 cos i + n2 cos t), t_p = 2 n1 cos i / (n2 cos i +
    /// n1 cos t) and the beam's change of cross-section, T = n2 cos t / (n1 cos i) ·
    /// (t_s² + t_p²)/2. A swapped n1/n2 or cos in `rs`/`rp` breaks it by 1e-2 or more.
    #[test]
    fn reflectance_and_transmittance_sum_to_one() {
        for (n1, n2) in [(1.0, 1.5), (1.5, 1.0), (1.0, 2.4), (1.33, 1.0)] {
            for k in 0..=40 {
                let cos_i = 0.01 + 0.99 * k as f64 / 40.0;
                let r = fresnel_dielectric(cos_i, n1, n2);
                let sin2_t = (n1 / n2) * (n1 / n2) * (1.0 - cos_i * cos_i);
                if sin2_t >= 1.0 {
                    assert_eq!(r, 1.0, "total internal reflection");
                    continue;
                }
                let cos_t = (1.0 - sin2_t).sqrt();
                let ts = 2.0 * n1 * cos_i / (n1 * cos_i + n2 * cos_t);
                let tp = 2.0 * n1 * cos_i / (n2 * cos_i + n1 * cos_t);
                let t = n2 * cos_t / (n1 * cos_i) * 0.5 * (ts * ts + tp * tp);
                assert!(
                    (r + t - 1.0).abs() < 1e-12,
                    "{n1}->{n2} cos {cos_i}: R {r} T {t}"
                );
            }
        }
    }

    /// Snell's law holds for the refracted direction, which stays in the plane of incidence
    /// on the far side; past the critical angle (41.8° out of n = 1.5) there is none.
    #[test]
    fn refraction_obeys_snell_and_total_internal_reflection() {
        let n = DVec3::Y;
        for deg in [0.0f64, 20.0, 40.0, 60.0, 85.0] {
            let a = deg.to_radians();
            let d = DVec3::new(a.sin(), -a.cos(), 0.0);
            let t = refract(d, n, 1.0, 1.5).expect("entering never reflects totally");
            assert!((t.length() - 1.0).abs() < 1e-12);
            assert!(t.y < 0.0 && t.z.abs() < 1e-12);
            assert!((1.0 * a.sin() - 1.5 * t.x).abs() < 1e-12, "{deg}°");
        }
        let critical = (1.0f64 / 1.5).asin();
        let inside = |a: f64| DVec3::new(a.sin(), -a.cos(), 0.0);
        assert!(refract(inside(critical - 0.01), n, 1.5, 1.0).is_some());
        assert!(refract(inside(critical + 0.01), n, 1.5, 1.0).is_none());
        let i = dielectric(inside(critical + 0.01), -n, false, 1.5);
        assert_eq!(i.reflectance, 1.0);
        assert!(i.refracted.is_none());
    }

    /// The lobe against quadrature. The fraction of directions kept (above the surface) is
    /// ∫ (n + 1)/(2π) cosⁿα dω over the lobe's part above the surface, summed on a 400 × 800
    /// (θ, φ) midpoint grid of the hemisphere: 1 at normal incidence for every n, less at 60°
    /// (0.75 for n = 0). The sampled directions' mean cos α is (n + 1)/(n + 2)
    /// (∫cosⁿ⁺¹α / ∫cosⁿα). 40,000 stratified samples: the estimates are good to 1e-3; a
    /// lobe around the normal or an exponent off by one moves them by 0.01 or more.
    #[test]
    fn the_phong_lobe_matches_its_integrals() {
        use std::f64::consts::PI;
        let normal = DVec3::Z;
        for exponent in [0.0f64, 5.0, 60.0] {
            for deg in [0.0f64, 60.0] {
                let a = deg.to_radians();
                let incoming = DVec3::new(a.sin(), 0.0, -a.cos());
                let axis = reflect(incoming, normal);
                let (nt, np) = (400, 800);
                let mut albedo = 0.0;
                for i in 0..nt {
                    let th = (i as f64 + 0.5) / nt as f64 * 0.5 * PI;
                    for j in 0..np {
                        let ph = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                        let w = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                        let cos_a = w.dot(axis);
                        if cos_a <= 0.0 {
                            continue; // beyond the lobe (α > 90°)
                        }
                        albedo += (exponent + 1.0) / (2.0 * PI)
                            * cos_a.powf(exponent)
                            * th.sin()
                            * (0.5 * PI / nt as f64)
                            * (2.0 * PI / np as f64);
                    }
                }
                if deg == 0.0 {
                    assert!((albedo - 1.0).abs() < 1e-3, "quadrature {albedo}");
                }
                let m = 200;
                let (mut weight, mut cos_a, mut count) = (0.0, 0.0, 0.0);
                for i in 0..m {
                    for j in 0..m {
                        let u1 = (i as f64 + 0.5) / m as f64;
                        let u2 = (j as f64 + 0.5) / m as f64;
                        count += 1.0;
                        let Some(dir) = phong_lobe(axis, normal, exponent, u1, u2) else {
                            continue;
                        };
                        assert!((dir.length() - 1.0).abs() < 1e-9);
                        weight += 1.0;
                        cos_a += dir.dot(axis);
                    }
                }
                let (weight, cos_a) = (weight / count, cos_a / count);
                assert!(
                    (weight - albedo).abs() < 2e-3,
                    "n {exponent}, {deg}°: kept {weight}, quadrature {albedo}"
                );
                if deg == 0.0 {
                    let want = (exponent + 1.0) / (exponent + 2.0);
                    assert!(
                        (cos_a - want).abs() < 1e-3,
                        "n {exponent}: mean cos α {cos_a}, want {want}"
                    );
                }
            }
        }
    }
}
