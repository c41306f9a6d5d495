//! Seeded random numbers and sampling helpers.
//!
//! `Rng` is PCG32 (O'Neill 2014): small, fast, and reproducible across platforms, so every
//! stochastic result in Nusselt is a pure function of its seed.

use glam::DVec3;

/// PCG32 random number generator (XSH-RR output, 64-bit state).
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// A generator for `seed` on stream `stream` (independent sequences per stream).
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Rng {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(splitmix(seed));
        rng.next_u32();
        rng
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        ((hi | lo) as f64) * (1.0 / (1u64 << 53) as f64)
    }
}

/// SplitMix64 finaliser: decorrelates nearby seeds.
pub fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hashes several integers into one seed (for per-pixel / per-pair streams).
pub fn hash_seed(parts: &[u64]) -> u64 {
    parts
        .iter()
        .fold(0x2545_F491_4F6C_DD1Du64, |h, &p| splitmix(h ^ p))
}

/// An orthonormal basis (t, b, n) around unit `n` (Duff et al. 2017).
pub fn basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Cosine-weighted direction about unit `n` from two uniforms.
pub fn cosine_hemisphere(n: DVec3, u1: f64, u2: f64) -> DVec3 {
    let r = u1.sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let (t, b) = basis(n);
    let z = (1.0 - u1).max(0.0).sqrt();
    t * (r * phi.cos()) + b * (r * phi.sin()) + n * z
}

/// Uniform point in triangle (a, b, c) from two uniforms.
pub fn triangle_point(a: DVec3, b: DVec3, c: DVec3, u1: f64, u2: f64) -> DVec3 {
    let s = u1.sqrt();
    a * (1.0 - s) + b * (s * (1.0 - u2)) + c * (s * u2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_deterministic_and_uniform() {
        let mut a = Rng::new(7, 1);
        let mut b = Rng::new(7, 1);
        let mut c = Rng::new(7, 2);
        let mut sum = 0.0;
        let mut differs = false;
        for _ in 0..10_000 {
            let x = a.next_f64();
            assert_eq!(x, b.next_f64());
            differs |= x != c.next_f64();
            assert!((0.0..1.0).contains(&x));
            sum += x;
        }
        assert!(differs);
        assert!((sum / 10_000.0 - 0.5).abs() < 0.01);
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            DVec3::X,
            DVec3::NEG_Z,
            DVec3::new(0.3, -0.4, 0.5).normalize_or_zero(),
        ] {
            let (t, b) = basis(n);
            assert!(t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12 && t.dot(b).abs() < 1e-12);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
        }
    }
}
