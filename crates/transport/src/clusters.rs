//! A volume hierarchy over the scene's polygons for the first linking pass: which polygon pairs
//! are worth linking at all.
//!
//! Linking from every polygon pair costs O(P²) screens even where walls hide most pairs (an
//! office floor: each room sees itself, its neighbours and what the doors let through). The
//! first pass therefore starts from the root cluster pair and descends (Smits, Arvo &
//! Greenberg 1994 start their links the same way): a pair of disjoint clusters whose every
//! sampled shadow ray is blocked, and whose light the rays can have missed is within the link
//! tolerance, is dropped; any other pair is split until both sides are single polygons, which
//! are then linked as before. Dropped pairs are kept and re-tested with more rays when a later
//! pass's radiosities call for them.
//!
//! The bound (for the receiver side C of a pair, and the same with C and D swapped): the mean
//! irradiance over C from D is `(1/A_C) ∫_C ∫_D B(y) K V dy dx ≤ Φ_D / (π d²) · P`, with
//! `Φ_D = Σ_{q ∈ D} A_q B_q` the power D can emit, `d` the distance between the two boxes
//! (`K = cos θ cos θ' / (π r²) ≤ 1 / (π d²)`), and `P` the probability that a point x uniform
//! by area on C and a point y drawn by power on D face each other and see each other. With n
//! such rays all blocked, `P ≤ 3 / n` (the "rule of three", 95%). The pair is dropped when
//! `ρ_C · Φ_D / (π d²) · 3 / n ≤ ε` both ways; `n` is chosen as the least count that meets it,
//! at most [`MAX_RAYS`]. Like every shadow-ray decision this is statistical; its error is the
//! link tolerance's.
//!
//! This module is not the cluster transport of part 2 (links between clusters carrying light):
//! every light-carrying link still joins two polygon hierarchies.

use form_factor::Surface;
use glam::DVec3;
use visibility::Occluders;
use visibility::{pair_seed, SplitMix64};

/// Most shadow rays one cluster pair gets per direction; a pair that would need more is split.
pub(crate) const MAX_RAYS: u32 = 128;

/// A node of the cluster tree: polygons `order[first..first + count]`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cluster {
    pub lo: DVec3,
    pub hi: DVec3,
    pub first: u32,
    pub count: u32,
    /// The two halves, `None` for a single polygon.
    pub children: Option<[u32; 2]>,
}

/// The cluster tree: node 0 is the root.
pub(crate) struct Clusters {
    pub nodes: Vec<Cluster>,
    /// Polygon indices (into the caller's root list), grouped by cluster.
    pub order: Vec<u32>,
}

impl Clusters {
    /// Median splits of the polygons' centroids along the longest axis of their bounds, down
    /// to single polygons. Ties are broken by index, so the tree does not depend on the thread
    /// count or the sort algorithm.
    pub fn new(surfaces: &[Surface]) -> Clusters {
        let mut order: Vec<u32> = (0..surfaces.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * surfaces.len());
        if !surfaces.is_empty() {
            nodes.push(placeholder());
            build(surfaces, &mut order, 0, 0, &mut nodes);
        }
        Clusters { nodes, order }
    }
}

fn placeholder() -> Cluster {
    Cluster {
        lo: DVec3::ZERO,
        hi: DVec3::ZERO,
        first: 0,
        count: 0,
        children: None,
    }
}

/// Fills node `at` with `order[first..first + slice.len()]`, creating its subtree.
fn build(surfaces: &[Surface], slice: &mut [u32], first: u32, at: usize, nodes: &mut Vec<Cluster>) {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let (mut clo, mut chi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for &k in slice.iter() {
        let s = &surfaces[k as usize];
        for c in &s.corners[..usize::from(s.sides)] {
            lo = lo.min(*c);
            hi = hi.max(*c);
        }
        clo = clo.min(s.centroid);
        chi = chi.max(s.centroid);
    }
    let count = slice.len() as u32;
    nodes[at] = Cluster {
        lo,
        hi,
        first,
        count,
        children: None,
    };
    if slice.len() < 2 {
        return;
    }
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    slice.sort_unstable_by(|&a, &b| {
        let (ca, cb) = (surfaces[a as usize].centroid, surfaces[b as usize].centroid);
        ca[axis].total_cmp(&cb[axis]).then(a.cmp(&b))
    });
    let half = slice.len() / 2;
    let (left, right) = slice.split_at_mut(half);
    let l = nodes.len();
    nodes.push(placeholder());
    nodes.push(placeholder());
    nodes[at].children = Some([l as u32, l as u32 + 1]);
    build(surfaces, left, first, l, nodes);
    build(surfaces, right, first + half as u32, l + 1, nodes);
}

/// The distance between two boxes (0 when they touch or overlap).
pub(crate) fn box_distance(a: &Cluster, b: &Cluster) -> f64 {
    let gap = (a.lo - b.hi).max(b.lo - a.hi).max(DVec3::ZERO);
    gap.length()
}

/// Per-cluster sums for one pass: the largest ρ and the power `Σ A B` of each cluster's polygons, and the
/// prefix sums over `order` that draw a polygon by area or by power.
pub(crate) struct Weights {
    pub power: Vec<f64>,
    pub rho: Vec<f64>,
    /// `prefix_area[k]` = Σ of the areas of `order[..k]`; likewise power.
    prefix_area: Vec<f64>,
    prefix_power: Vec<f64>,
}

impl Weights {
    /// `b` and `rho` per polygon (the caller's root list).
    pub fn new(clusters: &Clusters, surfaces: &[Surface], b: &[f64], rho: &[f64]) -> Weights {
        let m = clusters.order.len();
        let mut prefix_area = Vec::with_capacity(m + 1);
        let mut prefix_power = Vec::with_capacity(m + 1);
        let (mut a, mut p) = (0.0, 0.0);
        prefix_area.push(0.0);
        prefix_power.push(0.0);
        for &k in &clusters.order {
            let s = &surfaces[k as usize];
            a += s.area;
            p += s.area * b[k as usize];
            prefix_area.push(a);
            prefix_power.push(p);
        }
        let mut power = Vec::with_capacity(clusters.nodes.len());
        let mut rho_max = Vec::with_capacity(clusters.nodes.len());
        for c in &clusters.nodes {
            let (f, l) = (c.first as usize, (c.first + c.count) as usize);
            power.push(prefix_power[l] - prefix_power[f]);
            let r = clusters.order[f..l]
                .iter()
                .map(|&k| rho[k as usize])
                .fold(0.0f64, f64::max);
            rho_max.push(r);
        }
        Weights {
            power,
            rho: rho_max,
            prefix_area,
            prefix_power,
        }
    }

    /// The polygon (index into `order`) of cluster `c` at fraction `u ∈ [0, 1)` of its area
    /// (`by_power`: of its power).
    fn draw(&self, c: &Cluster, u: f64, by_power: bool) -> usize {
        let prefix = if by_power {
            &self.prefix_power
        } else {
            &self.prefix_area
        };
        let (f, l) = (c.first as usize, (c.first + c.count) as usize);
        let target = prefix[f] + u * (prefix[l] - prefix[f]);
        // The first k in f..l with prefix[k + 1] > target.
        let k = f + prefix[f + 1..=l].partition_point(|&v| v <= target);
        k.min(l - 1)
    }
}

/// Rays that make the pair's missed light `ρ Φ / (π d²) · 3 / n` at most `epsilon`, per
/// direction (into a, into b); `None` when more than [`MAX_RAYS`] would be needed (or the
/// boxes touch).
pub(crate) fn rays_needed(
    weights: &Weights,
    a: u32,
    b: u32,
    distance: f64,
    epsilon: f64,
) -> Option<[u32; 2]> {
    if distance <= 0.0 {
        return None;
    }
    let kernel = 1.0 / (std::f64::consts::PI * distance * distance);
    let need = |receiver: u32, source: u32| -> Option<u32> {
        let missed = weights.rho[receiver as usize] * weights.power[source as usize] * kernel;
        if missed <= 0.0 {
            return Some(0);
        }
        if epsilon.is_nan() || epsilon <= 0.0 {
            return None;
        }
        let n = (3.0 * missed / epsilon).ceil();
        (n <= f64::from(MAX_RAYS)).then_some((n as u32).max(1))
    };
    Some([need(a, b)?, need(b, a)?])
}

/// Whether every one of `rays` sampled point pairs (x on `receiver` by area, y on `source` by
/// power) fails to face or is blocked. `surfaces` and `polygon` are per caller polygon: the
/// polygon's surface and its index among the occluders.
#[allow(clippy::too_many_arguments)]
pub(crate) fn all_blocked(
    clusters: &Clusters,
    weights: &Weights,
    surfaces: &[Surface],
    polygon: &[u32],
    occluders: &Occluders,
    receiver: u32,
    source: u32,
    rays: u32,
    seed: u64,
) -> (bool, u32) {
    let (rc, sc) = (
        &clusters.nodes[receiver as usize],
        &clusters.nodes[source as usize],
    );
    let mut rng = SplitMix64::new(pair_seed(receiver as usize, source as usize) ^ seed);
    let lift = occluders.ray_offset();
    let n = rays.max(1);
    let mut cast = 0;
    for k in 0..n {
        // Stratified over both clusters' polygons (the source's strata reversed, so the
        // pairs do not line up).
        let ux = (f64::from(k) + rng.next_f64()) / f64::from(n);
        let uy = (f64::from(n - 1 - k) + rng.next_f64()) / f64::from(n);
        let i = clusters.order[weights.draw(rc, ux, false)] as usize;
        let j = clusters.order[weights.draw(sc, uy, true)] as usize;
        let (si, sj) = (&surfaces[i], &surfaces[j]);
        let x = point_on(si, rng.next_f64(), rng.next_f64());
        let y = point_on(sj, rng.next_f64(), rng.next_f64());
        let d = y - x;
        if si.normal.dot(d) <= 0.0 || sj.normal.dot(d) >= 0.0 {
            continue;
        }
        cast += 1;
        // Glass lets part of the light through: only an opaque hit blocks.
        let passed = occluders.segment_transmittance(
            x + si.normal * lift,
            y + sj.normal * lift,
            [polygon[i] as usize, polygon[j] as usize],
        );
        if passed > 0.0 {
            return (false, cast);
        }
    }
    (true, cast)
}

/// A point uniform by area on a triangle or convex quad (a fan of two triangles).
fn point_on(s: &Surface, u: f64, v: f64) -> DVec3 {
    let c = &s.corners;
    let tri = |a: DVec3, b: DVec3, d: DVec3, u: f64, v: f64| {
        let r = u.sqrt();
        a * (1.0 - r) + b * (r * (1.0 - v)) + d * (r * v)
    };
    if s.sides == 3 {
        return tri(c[0], c[1], c[2], u, v);
    }
    let a1 = (c[1] - c[0]).cross(c[2] - c[0]).length();
    let a2 = (c[2] - c[0]).cross(c[3] - c[0]).length();
    let split = a1 / (a1 + a2).max(f64::MIN_POSITIVE);
    if u < split {
        tri(c[0], c[1], c[2], u / split, v)
    } else {
        tri(
            c[0],
            c[2],
            c[3],
            (u - split) / (1.0 - split).max(f64::MIN_POSITIVE),
            v,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(at: DVec3) -> Surface {
        let n = DVec3::Z;
        Surface::new(
            &[at, at + DVec3::X, at + DVec3::X + DVec3::Y, at + DVec3::Y],
            n,
        )
        .expect("a unit square")
    }

    #[test]
    fn tree_covers_every_polygon_once_and_boxes_nest() {
        let surfaces: Vec<Surface> = (0..37)
            .map(|k| {
                square(DVec3::new(
                    f64::from(k % 7) * 2.0,
                    f64::from(k / 7) * 3.0,
                    0.0,
                ))
            })
            .collect();
        let c = Clusters::new(&surfaces);
        assert_eq!(c.nodes.len(), 2 * 37 - 1);
        let mut seen = c.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..37).collect::<Vec<u32>>());
        for node in &c.nodes {
            if let Some([l, r]) = node.children {
                let (l, r) = (&c.nodes[l as usize], &c.nodes[r as usize]);
                assert_eq!(l.count + r.count, node.count);
                assert_eq!(l.first, node.first);
                assert_eq!(r.first, node.first + l.count);
                for child in [l, r] {
                    assert!(child.lo.cmpge(node.lo).all() && child.hi.cmple(node.hi).all());
                }
            } else {
                assert_eq!(node.count, 1);
            }
        }
    }

    #[test]
    fn box_distance_is_the_gap() {
        let a = Cluster {
            lo: DVec3::ZERO,
            hi: DVec3::ONE,
            ..placeholder()
        };
        let b = Cluster {
            lo: DVec3::new(4.0, 5.0, 0.5),
            hi: DVec3::new(6.0, 6.0, 2.0),
            ..placeholder()
        };
        assert!((box_distance(&a, &b) - 5.0).abs() < 1e-15);
        assert_eq!(box_distance(&a, &a), 0.0);
    }

    #[test]
    fn drawing_by_area_follows_the_prefix_sums() {
        let surfaces = vec![square(DVec3::ZERO), square(DVec3::X * 3.0)];
        let c = Clusters::new(&surfaces);
        let w = Weights::new(&c, &surfaces, &[1.0, 3.0], &[0.5, 0.5]);
        let root = &c.nodes[0];
        assert_eq!(w.power[0], 4.0);
        // By power, polygon 1 (B = 3) takes the last three quarters.
        assert_eq!(c.order[w.draw(root, 0.2, true)], 0);
        assert_eq!(c.order[w.draw(root, 0.3, true)], 1);
        assert_eq!(c.order[w.draw(root, 0.49, false)], 0);
        assert_eq!(c.order[w.draw(root, 0.51, false)], 1);
        assert_eq!(c.order[w.draw(root, 0.999_999, false)], 1);
    }

    #[test]
    fn points_are_uniform_on_a_quad() {
        // A trapezoid: the mean of uniform points is its area centroid.
        let s = Surface::new(
            &[
                DVec3::ZERO,
                DVec3::new(4.0, 0.0, 0.0),
                DVec3::new(3.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
            ],
            DVec3::Z,
        )
        .expect("a trapezoid");
        let mut rng = SplitMix64::new(7);
        let n = 200_000;
        let mut sum = DVec3::ZERO;
        for _ in 0..n {
            sum += point_on(&s, rng.next_f64(), rng.next_f64());
        }
        let mean = sum / f64::from(n);
        assert!(
            (mean - s.centroid).length() < 5e-3,
            "{mean} vs {}",
            s.centroid
        );
    }
}
