//! Real spherical harmonics up to L2 in three.js's `SphericalHarmonics3` convention: nine
//! coefficients in the order (0,0), (1,−1), (1,0), (1,1), (2,−2), (2,−1), (2,0), (2,1), (2,2),
//! the basis functions as `SphericalHarmonics3.getBasisAt` writes them (y, z, x for band 1; xy,
//! yz, 3z² − 1, xz, x² − y² for band 2), with their exact constants.

use glam::DVec3;
use std::f64::consts::PI;

/// Coefficients per colour band.
pub const COEFFICIENTS: usize = 9;

/// Nine coefficients, each an RGB triple.
pub type Sh = [[f64; 3]; COEFFICIENTS];

/// The nine basis functions at the unit direction `d`.
#[inline]
pub fn basis(d: DVec3) -> [f64; COEFFICIENTS] {
    let c0 = 0.5 * (1.0 / PI).sqrt();
    let c1 = (3.0 / (4.0 * PI)).sqrt();
    let c2 = 0.5 * (15.0 / PI).sqrt();
    let c20 = 0.25 * (5.0 / PI).sqrt();
    let c22 = 0.25 * (15.0 / PI).sqrt();
    let (x, y, z) = (d.x, d.y, d.z);
    [
        c0,
        c1 * y,
        c1 * z,
        c1 * x,
        c2 * x * y,
        c2 * y * z,
        c20 * (3.0 * z * z - 1.0),
        c2 * x * z,
        c22 * (x * x - y * y),
    ]
}

/// The band of each coefficient.
pub const BAND: [usize; COEFFICIENTS] = [0, 1, 1, 1, 2, 2, 2, 2, 2];

/// The clamped-cosine kernel's coefficients Â_l = 2π/(2l+1) ∫ max(t, 0) P_l(t) dt for l ≤ 2:
/// π, 2π/3, π/4 (Ramamoorthi & Hanrahan 2001).
pub const KERNEL: [f64; 3] = [PI, 2.0 * PI / 3.0, PI / 4.0];

/// The irradiance `∫ L(ω) max(n·ω, 0) dω` that the truncated radiance `sh` gives a surface
/// of unit normal `n`: `Σ Â_l c_lm Y_lm(n)` (three.js's `shGetIrradianceAt`).
pub fn irradiance(sh: &Sh, n: DVec3) -> [f64; 3] {
    let y = basis(n);
    let mut out = [0.0; 3];
    for k in 0..COEFFICIENTS {
        for (o, c) in out.iter_mut().zip(sh[k]) {
            *o += KERNEL[BAND[k]] * c * y[k];
        }
    }
    out
}

/// Â_l of the clamped cosine for even l ≥ 2: `2π (−1)^(l/2−1) / ((l+2)(l−1)) · C(l, l/2) / 2^l`
/// (odd l > 1 give 0).
fn kernel_even(l: u32, binomial_over_power: f64) -> f64 {
    let sign = if (l / 2) % 2 == 1 { 1.0 } else { -1.0 };
    2.0 * PI * sign / (f64::from(l + 2) * f64::from(l - 1)) * binomial_over_power
}

/// `T = sqrt(Σ_{l ≥ 3} Â_l² (2l+1)/(4π))`: by Cauchy–Schwarz over the coefficients and the
/// addition theorem (`Σ_m Y_lm(n)² = (2l+1)/(4π)`), the irradiance the L2 truncation misses
/// in any direction is at most `T · ‖L − L₂‖`, where `‖L − L₂‖² = ∫ L² dω − Σ c_lm²` is the
/// radiance's energy above band 2. T ≈ 0.128 (the series is summed to l = 20 000; its tail
/// past that is below 1e-12).
pub fn truncation_factor() -> f64 {
    // C(l, l/2) / 2^l, from l = 2 upward two at a time.
    let mut ratio = 0.5;
    let mut sum = 0.0;
    let mut l = 2u32;
    while l < 20_000 {
        let next = ratio * f64::from(l + 1) * f64::from(l + 2)
            / (4.0 * f64::from(l / 2 + 1) * f64::from(l / 2 + 1));
        l += 2;
        ratio = next;
        let a = kernel_even(l, ratio);
        sum += a * a * f64::from(2 * l + 1) / (4.0 * PI);
    }
    sum.sqrt()
}

/// Per band, the bound on the L2 truncation's irradiance error in any direction:
/// `T · sqrt(max(0, ∫ L² dω − Σ c²))` ([`truncation_factor`]).
pub fn truncation_bound(sh: &Sh, square: [f64; 3]) -> [f64; 3] {
    let t = truncation_factor();
    let mut out = [0.0; 3];
    for (band, o) in out.iter_mut().enumerate() {
        let kept: f64 = sh.iter().map(|c| c[band] * c[band]).sum();
        *o = t * (square[band] - kept).max(0.0).sqrt();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense midpoint quadrature over the sphere in (z, φ) (equal area).
    fn sphere(n: usize, mut f: impl FnMut(DVec3, f64)) {
        let w = 4.0 * PI / (n * 2 * n) as f64;
        for i in 0..n {
            let z = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            for j in 0..2 * n {
                let phi = PI * (j as f64 + 0.5) / n as f64;
                f(DVec3::new(s * phi.cos(), s * phi.sin(), z), w);
            }
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        let mut gram = [[0.0; 9]; 9];
        sphere(400, |d, w| {
            let y = basis(d);
            for a in 0..9 {
                for b in 0..9 {
                    gram[a][b] += y[a] * y[b] * w;
                }
            }
        });
        for (a, row) in gram.iter().enumerate() {
            for (b, g) in row.iter().enumerate() {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 1e-4, "<Y{a}, Y{b}> = {g}");
            }
        }
    }

    #[test]
    fn irradiance_of_a_projected_clamped_cosine_light() {
        // Radiance L(ω) = max(ω·a, 0)²: smooth enough that the quadrature is exact to 1e-5;
        // the reconstructed irradiance must match ∫ L max(n·ω, 0) within the stated bound.
        let a = DVec3::new(0.3, 0.8, -0.2).normalize();
        let radiance = |d: DVec3| d.dot(a).max(0.0).powi(2);
        let mut sh = [[0.0; 3]; 9];
        let mut square = [0.0; 3];
        sphere(600, |d, w| {
            let l = radiance(d);
            let y = basis(d);
            for k in 0..9 {
                sh[k][0] += l * y[k] * w;
            }
            square[0] += l * l * w;
        });
        let bound = truncation_bound(&sh, square)[0];
        for n in [DVec3::X, DVec3::Y, DVec3::Z, -DVec3::X, -DVec3::Y, a] {
            let mut exact = 0.0;
            sphere(600, |d, w| exact += radiance(d) * d.dot(n).max(0.0) * w);
            let got = irradiance(&sh, n)[0];
            assert!(
                (got - exact).abs() <= bound + 1e-5,
                "n {n}: {got} vs {exact}, bound {bound}"
            );
        }
        // The uniform case is exact: L = 1 gives π everywhere.
        let mut one = [[0.0; 3]; 9];
        one[0] = [(4.0 * PI).sqrt(); 3];
        assert!((irradiance(&one, DVec3::Y)[0] - PI).abs() < 1e-12);
    }

    #[test]
    fn truncation_factor_matches_its_series() {
        // Â_4 = −π/24: its term alone is (π/24)² · 9/(4π); the whole series is a little more.
        let t = truncation_factor();
        let first = (PI / 24.0).powi(2) * 9.0 / (4.0 * PI);
        assert!(t * t > first && t * t < 1.5 * first, "T = {t}");
    }
}
