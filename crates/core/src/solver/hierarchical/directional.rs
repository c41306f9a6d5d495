//! Directional irradiance of receiving clusters: second-order spherical harmonics.
//!
//! A cluster's elements face every way, so the light a cluster gathers is kept as a
//! function of the normal: each link adds a delta of normal-incidence irradiance `H` from
//! the direction `d` of its sender, projected on the nine real spherical harmonics of order
//! ≤ 2, and each element under the cluster reads `E(n) = Σ A_l L_lm Y_lm(n)` at its own
//! normal, with the clamped cosine's coefficients `A_0 = π, A_1 = 2π/3, A_2 = π/4`
//! (Ramamoorthi & Hanrahan 2001, "An efficient representation for irradiance environment
//! maps"). Known error for one direction: `E(n)` is within 0.11 `H` of `H max(n·d, 0)`
//! (1.0625 `H` facing the sender, 0.0625 `H` facing away); the refinement oracle charges
//! it to every cluster-received link.

use glam::DVec3;

use crate::scene::Rgb;

/// Nine coefficients per colour channel.
pub type Sh9 = [Rgb; 9];

/// Worst error of [`irradiance`] for one direction, relative to `H` (see the module docs).
pub const SH_ERROR: f64 = 0.11;

/// The real spherical harmonics of order ≤ 2 at unit direction `d`.
pub fn basis(d: DVec3) -> [f64; 9] {
    let (x, y, z) = (d.x, d.y, d.z);
    [
        0.282_094_791_773_878_1,
        0.488_602_511_902_919_9 * y,
        0.488_602_511_902_919_9 * z,
        0.488_602_511_902_919_9 * x,
        1.092_548_430_592_079_2 * x * y,
        1.092_548_430_592_079_2 * y * z,
        0.315_391_565_252_520_05 * (3.0 * z * z - 1.0),
        1.092_548_430_592_079_2 * x * z,
        0.546_274_215_296_039_6 * (x * x - y * y),
    ]
}

/// Adds normal-incidence irradiance `h` arriving from unit direction `d`.
pub fn add(sh: &mut Sh9, d: DVec3, h: Rgb) {
    for (c, y) in sh.iter_mut().zip(basis(d)) {
        *c += h * y;
    }
}

/// Irradiance on a surface of unit normal `n` (clamped at zero).
pub fn irradiance(sh: &Sh9, n: DVec3) -> Rgb {
    use std::f64::consts::PI;
    const A: [f64; 9] = [
        PI,
        2.0 * PI / 3.0,
        2.0 * PI / 3.0,
        2.0 * PI / 3.0,
        PI / 4.0,
        PI / 4.0,
        PI / 4.0,
        PI / 4.0,
        PI / 4.0,
    ];
    let y = basis(n);
    let mut e = Rgb::ZERO;
    for k in 0..9 {
        e += sh[k] * (A[k] * y[k]);
    }
    e.max(Rgb::ZERO)
}

/// The clamped cosine's coefficients per band (see the module docs).
fn band_weight(k: usize) -> f64 {
    use std::f64::consts::PI;
    match k {
        0 => PI,
        1..=3 => 2.0 * PI / 3.0,
        _ => PI / 4.0,
    }
}

/// One scalar function of direction in the same harmonics.
pub type Sh9Scalar = [f64; 9];

/// Adds `h max(n·d, 0)` as a function of `n` (a surface of normal `d` and weight `h`).
pub fn add_scalar(sh: &mut Sh9Scalar, d: DVec3, h: f64) {
    for (c, y) in sh.iter_mut().zip(basis(d)) {
        *c += h * y;
    }
}

/// `Σ h max(n·d, 0)` at unit `n` (clamped at zero), within [`SH_ERROR`] `Σ h`.
pub fn clamped_cosine_sum(sh: &Sh9Scalar, n: DVec3) -> f64 {
    let y = basis(n);
    (0..9)
        .map(|k| sh[k] * band_weight(k) * y[k])
        .sum::<f64>()
        .max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Rng;

    /// One direction against the exact clamped cosine, over many normals: within the
    /// stated error, and the known values facing the sender and facing away.
    #[test]
    fn one_direction_is_a_clamped_cosine_within_the_stated_error() {
        let mut rng = Rng::new(7, 0);
        for _ in 0..50 {
            let d = random_unit(&mut rng);
            let mut sh = [Rgb::ZERO; 9];
            add(&mut sh, d, Rgb::ONE);
            assert!((irradiance(&sh, d).x - 1.0625).abs() < 1e-9);
            assert!((irradiance(&sh, -d).x - 0.0625).abs() < 1e-9);
            for _ in 0..200 {
                let n = random_unit(&mut rng);
                let exact = n.dot(d).max(0.0);
                let e = irradiance(&sh, n).x;
                assert!((e - exact).abs() <= SH_ERROR, "{e} vs {exact}");
            }
        }
    }

    /// The projected area of a set of facets toward a direction: within the stated error
    /// of the exact `Σ A max(n·ω, 0)`; a sphere's is a quarter of its area every way.
    #[test]
    fn projected_area_of_facets_within_the_stated_error() {
        let mut rng = Rng::new(11, 0);
        let mut sh = [0.0; 9];
        let mut facets = Vec::new();
        for _ in 0..20 {
            let n = random_unit(&mut rng);
            let a = rng.next_f64();
            add_scalar(&mut sh, n, a);
            facets.push((n, a));
        }
        let total: f64 = facets.iter().map(|f| f.1).sum();
        for _ in 0..200 {
            let w = random_unit(&mut rng);
            let exact: f64 = facets.iter().map(|(n, a)| a * n.dot(w).max(0.0)).sum();
            let p = clamped_cosine_sum(&sh, w);
            assert!((p - exact).abs() <= SH_ERROR * total, "{p} vs {exact}");
        }
        let mut sphere = [0.0; 9];
        for _ in 0..20000 {
            add_scalar(&mut sphere, random_unit(&mut rng), 1.0 / 20000.0);
        }
        for _ in 0..20 {
            let p = clamped_cosine_sum(&sphere, random_unit(&mut rng));
            assert!((p - 0.25).abs() < 0.01, "{p}");
        }
    }

    fn random_unit(rng: &mut Rng) -> DVec3 {
        loop {
            let v = DVec3::new(
                2.0 * rng.next_f64() - 1.0,
                2.0 * rng.next_f64() - 1.0,
                2.0 * rng.next_f64() - 1.0,
            );
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }
}
