//! An equirectangular (latitude–longitude) environment map as a sky: radiance per direction
//! from an image, its exact illuminance on an unobstructed plane, and importance sampling of
//! it for rays (issue 35, `--sky map:FILE`).
//!
//! **Orientation** (+Y up, glTF's convention; the convention of three.js's `equirectUv` with
//! the image's first row at the top): texel (column c, row r) of a W × H image is the
//! direction of elevation `γ = π/2 − π (r + ½) / H` (row 0 at the zenith, the last row at the
//! nadir) and azimuth `φ = 2π (c + ½) / W − π`, `d = (cos γ cos φ, sin γ, cos γ sin φ)`: the
//! middle column looks along +X, three quarters across along +Z, a quarter across along −Z,
//! the left and right edges along −X. The lower half of the map is the ground: no
//! `--ground-reflectance` applies.
//!
//! **Sampling** (Pharr, Jakob & Humphreys, *Physically Based Rendering*, 3rd ed., §13.6.7
//! and §14.2.4): a piecewise-constant 2D distribution over the texels with weights
//! luminance × sin θ (θ = π/2 − γ the polar angle of the texel's centre), drawn as a marginal
//! over rows and a conditional over each row's columns, uniform inside the texel in (u, v);
//! the solid-angle density of the direction drawn is `p(u, v) / (2π² sin θ)`.

use glam::DVec3;
use std::f64::consts::PI;

/// Rec. 709 luminance weights: what the sampling distribution weighs the bands by.
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Most texels a map may have (16384 × 8192): the importer refuses a larger file before
/// decoding it.
pub use scene::MAX_SKY_MAP_TEXELS as MAX_MAP_TEXELS;

/// A map that cannot be a sky.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    #[error("the sky map {file} is {width} × {height}: expected an equirectangular image, twice as wide as high, with at most {MAX_MAP_TEXELS} texels")]
    Size {
        file: String,
        width: u64,
        height: u64,
    },
    #[error("the sky map {file} has a texel that is not a finite radiance ≥ 0 at column {column}, row {row}")]
    Texel {
        file: String,
        column: usize,
        row: usize,
    },
}

/// An equirectangular map of RGB radiance, ready for sampling.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Row-major, row 0 at the zenith.
    texels: Vec<[f32; 3]>,
    /// Per row, the running sum of the rows' weights (the marginal).
    rows: Vec<f64>,
    /// Per texel, the running sum of its row's weights up to it (the conditionals).
    columns: Vec<f64>,
}

impl EnvironmentMap {
    /// A map from its texels (row-major, row 0 at the zenith); `file` names it in errors.
    pub fn from_texels(
        file: &str,
        width: usize,
        height: usize,
        texels: Vec<[f32; 3]>,
    ) -> Result<EnvironmentMap, MapError> {
        if width == 0
            || height == 0
            || width != 2 * height
            || (width as u64) * (height as u64) > MAX_MAP_TEXELS
            || texels.len() != width * height
        {
            return Err(MapError::Size {
                file: file.to_string(),
                width: width as u64,
                height: height as u64,
            });
        }
        if let Some(k) = texels
            .iter()
            .position(|t| t.iter().any(|v| !(v.is_finite() && *v >= 0.0)))
        {
            return Err(MapError::Texel {
                file: file.to_string(),
                column: k % width,
                row: k / width,
            });
        }
        let mut columns = Vec::with_capacity(texels.len());
        let mut rows = Vec::with_capacity(height);
        let mut marginal = 0.0;
        for r in 0..height {
            let sin = (PI * (r as f64 + 0.5) / height as f64).sin();
            let mut sum = 0.0;
            for t in &texels[r * width..(r + 1) * width] {
                sum += luminance(t) * sin;
                columns.push(sum);
            }
            marginal += sum;
            rows.push(marginal);
        }
        Ok(EnvironmentMap {
            width,
            height,
            texels,
            rows,
            columns,
        })
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The unit direction of the point (u, v) of the map, u across and v down, in [0, 1].
    pub fn direction(u: f64, v: f64) -> DVec3 {
        let (elevation, azimuth) = (PI / 2.0 - PI * v, 2.0 * PI * u - PI);
        DVec3::new(
            elevation.cos() * azimuth.cos(),
            elevation.sin(),
            elevation.cos() * azimuth.sin(),
        )
    }

    /// The texel (column, row) direction `d` (unit) falls in.
    pub fn texel(&self, d: DVec3) -> (usize, usize) {
        let u = (d.z.atan2(d.x) + PI) / (2.0 * PI);
        let v = (PI / 2.0 - d.y.clamp(-1.0, 1.0).asin()) / PI;
        let column = ((u * self.width as f64) as usize).min(self.width - 1);
        let row = ((v * self.height as f64) as usize).min(self.height - 1);
        (column, row)
    }

    /// The radiance toward the unit direction `d`, per band.
    pub fn radiance(&self, d: DVec3) -> [f64; 3] {
        let (c, r) = self.texel(d);
        self.texels[r * self.width + c].map(f64::from)
    }

    /// The illuminance of an unobstructed plane of unit normal `n`, per band: the sum over
    /// texels of radiance × the texel's projected solid angle `∫ (d · n)⁺ dω` over the part
    /// of it in front of the plane — in closed form for texels (and parts of texels) wholly
    /// in front, by halving those the plane's horizon crosses six times and a midpoint rule
    /// on the last halves. Costs a pass over every texel.
    pub fn unobstructed(&self, n: DVec3) -> [f64; 3] {
        let (dt, dp) = (PI / self.height as f64, 2.0 * PI / self.width as f64);
        let mut sum = [0.0; 3];
        for r in 0..self.height {
            let t0 = r as f64 * dt;
            for c in 0..self.width {
                let p0 = c as f64 * dp - PI;
                let w = projected(n, t0, t0 + dt, p0, p0 + dp, 6);
                if w > 0.0 {
                    let t = self.texels[r * self.width + c];
                    for b in 0..3 {
                        sum[b] += w * f64::from(t[b]);
                    }
                }
            }
        }
        sum
    }

    /// Whether the map has any light to sample.
    pub fn is_dark(&self) -> bool {
        self.rows.last().is_none_or(|&total| total <= 0.0)
    }

    /// A direction drawn from (x, y) in [0, 1)² by the texels' weights (see the module
    /// docs), and its solid-angle density; `None` for a dark map.
    pub fn sample(&self, x: f64, y: f64) -> Option<(DVec3, f64)> {
        let total = *self.rows.last()?;
        if total <= 0.0 {
            return None;
        }
        let target = x * total;
        let r = self
            .rows
            .partition_point(|&s| s <= target)
            .min(self.height - 1);
        let row_start = if r == 0 { 0.0 } else { self.rows[r - 1] };
        let row = &self.columns[r * self.width..(r + 1) * self.width];
        let row_weight = self.rows[r] - row_start;
        // What is left of x picks the column in the row, then the position in the texel.
        let along = ((target - row_start) / row_weight).clamp(0.0, 1.0) * row_weight;
        let c = row.partition_point(|&s| s <= along).min(self.width - 1);
        let start = if c == 0 { 0.0 } else { row[c - 1] };
        let s = ((along - start) / (row[c] - start)).clamp(0.0, 1.0);
        let (u, v) = (
            (c as f64 + s) / self.width as f64,
            (r as f64 + y) / self.height as f64,
        );
        let d = Self::direction(u, v);
        Some((d, self.density(d)))
    }

    /// The solid-angle density with which [`EnvironmentMap::sample`] draws the unit
    /// direction `d`: `p(u, v) / (2π² sin θ)`, p the texel's weight × W H / total.
    pub fn density(&self, d: DVec3) -> f64 {
        let Some(&total) = self.rows.last() else {
            return 0.0;
        };
        let sin = (1.0 - d.y * d.y).max(0.0).sqrt();
        if total <= 0.0 || sin <= 0.0 {
            return 0.0;
        }
        let (c, r) = self.texel(d);
        let row_sin = (PI * (r as f64 + 0.5) / self.height as f64).sin();
        let weight = luminance(&self.texels[r * self.width + c]) * row_sin;
        let p_uv = weight * (self.width * self.height) as f64 / total;
        p_uv / (2.0 * PI * PI * sin)
    }
}

/// The size checks of [`EnvironmentMap::from_texels`], before the texels are read.
fn luminance(t: &[f32; 3]) -> f64 {
    (0..3).map(|b| LUMINANCE[b] * f64::from(t[b])).sum()
}

/// `∫∫ (d · n)⁺ sin θ dθ dφ` over θ in [t0, t1] (polar, from +Y), φ in [p0, p1], with
/// `d = (sin θ cos φ, cos θ, sin θ sin φ)` (the same as [`EnvironmentMap::direction`]:
/// cos γ = sin θ). Where `d · n ≥ 0` over the whole cell (checked at its corners, edge
/// midpoints and centre), the closed form `n_y (sin² t1 − sin² t0)/2 Δφ + B (n_x C + n_z D)`
/// with `B = ∫ sin² θ dθ`, `C = ∫ cos φ dφ`, `D = ∫ sin φ dφ`; where it is < 0 over all of
/// them, 0; else split in four, `depth` more times, then a midpoint rule.
fn projected(n: DVec3, t0: f64, t1: f64, p0: f64, p1: f64, depth: u32) -> f64 {
    let dot = |t: f64, p: f64| n.y * t.cos() + t.sin() * (n.x * p.cos() + n.z * p.sin());
    let (tm, pm) = ((t0 + t1) / 2.0, (p0 + p1) / 2.0);
    let probes = [
        dot(t0, p0),
        dot(t0, pm),
        dot(t0, p1),
        dot(tm, p0),
        dot(tm, pm),
        dot(tm, p1),
        dot(t1, p0),
        dot(t1, pm),
        dot(t1, p1),
    ];
    if probes.iter().all(|&v| v >= 0.0) {
        let a = (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
        let b = (t1 - t0) / 2.0 - ((2.0 * t1).sin() - (2.0 * t0).sin()) / 4.0;
        let c = p1.sin() - p0.sin();
        let d = p0.cos() - p1.cos();
        return (n.y * a * (p1 - p0) + b * (n.x * c + n.z * d)).max(0.0);
    }
    if probes.iter().all(|&v| v <= 0.0) {
        return 0.0;
    }
    if depth == 0 {
        return dot(tm, pm).max(0.0) * tm.sin() * (t1 - t0) * (p1 - p0);
    }
    projected(n, t0, tm, p0, pm, depth - 1)
        + projected(n, t0, tm, pm, p1, depth - 1)
        + projected(n, tm, t1, p0, pm, depth - 1)
        + projected(n, tm, t1, pm, p1, depth - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(width: usize, value: f32) -> EnvironmentMap {
        let height = width / 2;
        EnvironmentMap::from_texels("constant", width, height, vec![[value; 3]; width * height])
            .expect("a map")
    }

    /// A constant map of radiance L gives a plane tilted β from up `π L` (the whole sphere
    /// in front of it is the map, sky and ground alike), at every tilt, within 1e-6.
    #[test]
    fn a_constant_map_gives_pi_l_on_any_plane() {
        let map = constant(64, 2.5);
        for beta in [0.0f64, 0.3, 1.0, PI / 2.0, 2.2, PI] {
            for phi in [0.0f64, 0.7, 2.0] {
                let n = DVec3::new(beta.sin() * phi.cos(), beta.cos(), beta.sin() * phi.sin());
                let e = map.unobstructed(n);
                assert!(
                    (e[1] - PI * 2.5).abs() < 1e-6 * PI * 2.5,
                    "β {beta}, φ {phi}: {e:?}"
                );
            }
        }
    }

    /// One bright texel: a plane facing any way gets the texel's radiance × its solid angle
    /// × the cosine to its centre (a directional light of that illuminance), to the texel's
    /// own size; the texel's direction and the orientation convention agree.
    #[test]
    fn one_bright_texel_is_a_directional_light() {
        let (w, h) = (256, 128);
        let (column, row) = (150, 40);
        let mut texels = vec![[0f32; 3]; w * h];
        texels[row * w + column] = [1000.0, 500.0, 250.0];
        let map = EnvironmentMap::from_texels("one", w, h, texels).expect("a map");
        let centre = EnvironmentMap::direction(
            (column as f64 + 0.5) / w as f64,
            (row as f64 + 0.5) / h as f64,
        );
        assert_eq!(map.texel(centre), (column, row));
        let (dt, dp) = (PI / h as f64, 2.0 * PI / w as f64);
        let theta = (row as f64 + 0.5) * dt;
        let solid = dp * ((row as f64 * dt).cos() - ((row + 1) as f64 * dt).cos());
        for n in [DVec3::Y, centre, DVec3::new(0.3, 0.8, -0.5).normalize()] {
            let e = map.unobstructed(n);
            let directional = 1000.0 * solid * centre.dot(n);
            assert!(
                (e[0] - directional).abs() < 1e-3 * directional,
                "{n}: {} against {directional}",
                e[0]
            );
            assert!((e[1] - e[0] / 2.0).abs() < 1e-12 * e[0]);
        }
        assert!(theta > 0.0);
        // Conventions: the middle column looks along +X, three quarters along +Z, the top
        // row at the zenith.
        let at = |u: f64, v: f64| EnvironmentMap::direction(u, v);
        assert!((at(0.5, 0.5) - DVec3::X).length() < 1e-12);
        assert!((at(0.75, 0.5) - DVec3::Z).length() < 1e-12);
        assert!((at(0.25, 0.5) + DVec3::Z).length() < 1e-12);
        assert!((at(0.3, 0.0) - DVec3::Y).length() < 1e-12);
    }

    /// The sampling density integrates to 1 over the sphere, and drawn directions carry the
    /// density [`EnvironmentMap::density`] gives: an estimate of the map's unobstructed
    /// illuminance by importance sampling matches the exact sum.
    #[test]
    fn importance_sampling_is_unbiased() {
        let (w, h) = (64, 32);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|k| {
                let (c, r) = (k % w, k / w);
                let v = 0.1 + ((c * 7 + r * 13) % 17) as f32 + if r < 8 { 30.0 } else { 0.0 };
                [v, v * 0.5, v * 0.25]
            })
            .collect();
        let map = EnvironmentMap::from_texels("varied", w, h, texels).expect("a map");
        let cells = 600;
        let (dt, dp) = (PI / cells as f64, 2.0 * PI / (2 * cells) as f64);
        let mut sum = 0.0;
        for a in 0..cells {
            let theta = (a as f64 + 0.5) * dt;
            for c in 0..2 * cells {
                let phi = (c as f64 + 0.5) * dp - PI;
                let d = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                sum += map.density(d) * theta.sin() * dt * dp;
            }
        }
        assert!((sum - 1.0).abs() < 2e-3, "∫ p dω = {sum}");
        let n = DVec3::new(0.2, 0.9, 0.1).normalize();
        let exact = map.unobstructed(n)[0];
        let k = 400;
        let mut estimate = 0.0;
        for i in 0..k {
            for j in 0..k {
                let (x, y) = ((i as f64 + 0.5) / k as f64, (j as f64 + 0.5) / k as f64);
                let (d, p) = map.sample(x, y).expect("a lit map");
                let cos = d.dot(n);
                if cos > 0.0 && p > 0.0 {
                    estimate += map.radiance(d)[0] * cos / p;
                }
            }
        }
        estimate /= (k * k) as f64;
        assert!(
            (estimate - exact).abs() < 2e-3 * exact,
            "{estimate} against {exact}"
        );
    }

    #[test]
    fn maps_that_are_not_refused_with_their_name() {
        let bad = EnvironmentMap::from_texels("a.hdr", 10, 10, vec![[0.0; 3]; 100]);
        assert!(matches!(bad, Err(MapError::Size { .. })));
        let nan = EnvironmentMap::from_texels("b.hdr", 4, 2, vec![[f32::NAN; 3]; 8]);
        assert!(matches!(
            nan,
            Err(MapError::Texel {
                row: 0,
                column: 0,
                ..
            })
        ));
    }
}
