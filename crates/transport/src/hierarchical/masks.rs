//! Shadow masks: where a node gathers light over links that some polygon can come between,
//! push–pull hands that light to the node's elements by their own view of the node's sources,
//! not by area alone (issue 31).
//!
//! A link between coarse nodes carries the right total (its visible fraction comes from shadow
//! rays between the two nodes), but pushed down evenly it lights the elements under a desk as
//! much as those beside it, and their reflection then reaches the desk's back face and leaves
//! the scene. For each interior node with such links, every element i under it casts
//! [`MASK_RAYS`] shadow rays to points on the node's link partners, chosen in proportion to
//! each link's share of the node's light; its seen fraction w_i (0 where no ray arrives, or
//! where it does not face the sources) gives the scale `s_i = w_i A / Σ_j a_j w_j`, so
//! `Σ a_i s_i = A`: the node's gathered light is redistributed, never made or lost. A node
//! whose elements saw nothing keeps the even spread (`s_i = 1`).
//!
//! The same scales weight the node's radiosity when it is the source of those links
//! (`x_w = Σ a_i s_i x_i / A`, the first moment likewise about the weighted centroid), so the
//! element-level operator stays exactly reciprocal, `A_i F_ij = A_j F_ji`, as with the even
//! spread (an element hidden from q neither receives from q nor sends to it).

use super::*;
use visibility::SplitMix64;

/// Shadow rays per element of a masked node (5 × 5 strata on the element). Measured against
/// the dense transport of the same mesh (docs/accuracy.md): with 16 the Cornell box kept 1
/// of its 50 hidden elements lit and a worst element 10.1 % of the mean b off; with 25 none,
/// and 9.96 %.
pub(super) const MASK_RAYS: u32 = 25;

/// No mask (a leaf, or a node without occludable links).
pub(super) const NONE: u32 = u32::MAX;

/// The masks of the masked nodes, in node order.
#[derive(Clone, Debug, Default)]
pub(super) struct Masks {
    /// Per node: the index of its mask, or [`NONE`].
    pub(super) of_node: Vec<u32>,
    /// Per mask: its node, and its entries `offsets[m]..offsets[m + 1]`.
    pub(super) node: Vec<u32>,
    pub(super) offsets: Vec<u64>,
    /// Per mask: the centroid of its elements weighted by `a_i s_i`.
    pub(super) centroid: Vec<DVec3>,
    /// Per entry: the element and its scale `s_i`.
    pub(super) leaves: Vec<u32>,
    pub(super) scale: Vec<f64>,
    /// Shadow rays cast to make them.
    pub(super) rays: u64,
}

/// Whether a link's light goes through the masks of its interior ends: it carries light and
/// either some polygon can come between its nodes or one straddles the other's plane.
pub(super) fn masked(l: &Link) -> bool {
    l.g != 0.0 && (l.occludable || l.clipped)
}

impl Masks {
    /// No masks over `total` nodes (every link spreads evenly).
    pub(super) fn none(total: usize) -> Masks {
        Masks {
            of_node: vec![NONE; total],
            offsets: vec![0],
            ..Masks::default()
        }
    }

    /// The masks of every interior node with entries flagged `masked` (none when `entries`
    /// were assembled without masks). A node's partners are its masked entries' sources,
    /// weighted by their coefficients `G / A` (the node's area is common to them).
    pub(super) fn build(
        nodes: &[Node],
        children: &[u32],
        n: usize,
        entries: &Entries,
        occluders: &Occluders,
    ) -> Masks {
        let total = nodes.len();
        let partners = |r: usize| {
            let range = entries.offsets[r] as usize..entries.offsets[r + 1] as usize;
            range
                .filter(|&k| entries.masked[k])
                .map(|k| (entries.sources[k], entries.coefficients[k]))
                .collect::<Vec<(u32, f64)>>()
        };
        let masked_nodes: Vec<u32> = (n..total)
            .filter(|&r| {
                let range = entries.offsets[r] as usize..entries.offsets[r + 1] as usize;
                entries.masked[range].contains(&true)
            })
            .map(|r| r as u32)
            .collect();
        let made: Vec<(Vec<u32>, Vec<f64>, DVec3, u64)> = masked_nodes
            .par_iter()
            .map(|&r| {
                let r = r as usize;
                mask(nodes, children, n, r, &partners(r), occluders)
            })
            .collect();
        let mut masks = Masks::none(total);
        for (&r, (leaves, scale, centroid, rays)) in masked_nodes.iter().zip(made) {
            masks.of_node[r as usize] = masks.node.len() as u32;
            masks.node.push(r);
            masks.leaves.extend(leaves);
            masks.scale.extend(scale);
            masks.offsets.push(masks.leaves.len() as u64);
            masks.centroid.push(centroid);
            masks.rays += rays;
        }
        masks
    }

    /// Entries of mask `m`.
    pub(super) fn range(&self, m: usize) -> std::ops::Range<usize> {
        self.offsets[m] as usize..self.offsets[m + 1] as usize
    }
}

/// The elements under node `r` (depth first, children in order).
pub(super) fn leaves_under(nodes: &[Node], children: &[u32], n: usize, r: usize) -> Vec<u32> {
    let mut out = Vec::new();
    let mut stack = vec![r as u32];
    while let Some(u) = stack.pop() {
        if (u as usize) < n {
            out.push(u);
            continue;
        }
        let node = &nodes[u as usize];
        // Reversed, so that they are visited in order.
        stack.extend(
            children[node.first as usize..(node.first + node.count) as usize]
                .iter()
                .rev(),
        );
    }
    out
}

/// One node's mask: its elements, their scales, the weighted centroid and the rays cast.
fn mask(
    nodes: &[Node],
    children: &[u32],
    n: usize,
    r: usize,
    partners: &[(u32, f64)],
    occluders: &Occluders,
) -> (Vec<u32>, Vec<f64>, DVec3, u64) {
    let leaves = leaves_under(nodes, children, n, r);
    // Partners chosen by their share of the light: the cumulative values.
    let mut cumulative = Vec::with_capacity(partners.len());
    let mut sum = 0.0;
    for &(_, g) in partners {
        sum += g;
        cumulative.push(sum);
    }
    let side = (MASK_RAYS as f64).sqrt() as u32;
    let mut rays = 0u64;
    let seen: Vec<f64> = leaves
        .iter()
        .map(|&i| {
            let leaf = patch(&nodes[i as usize]);
            let mut rng = SplitMix64::new(pair_seed(r, i as usize));
            let mut visible = 0.0;
            for k in 0..MASK_RAYS {
                // The element's point in stratum k of a side × side grid; the partner by a
                // stratified draw over the values, its strata shuffled against the element's
                // (7 is prime to 25).
                let (su, sv) = (k % side, k / side);
                let ua = (f64::from(su) + rng.next_f64()) / f64::from(side);
                let va = (f64::from(sv) + rng.next_f64()) / f64::from(side);
                let stratum = (k * 7 + 3) % MASK_RAYS;
                let t = (f64::from(stratum) + rng.next_f64()) / f64::from(MASK_RAYS) * sum;
                let pick = cumulative
                    .partition_point(|&c| c <= t)
                    .min(partners.len() - 1);
                let source = patch(&nodes[partners[pick].0 as usize]);
                let uv = [ua, va, rng.next_f64(), rng.next_f64()];
                // Points that do not face each other exchange no light: not seen.
                // Glass passes its transmission of the ray.
                if let Some(passed) = occluders.point_pair_transmittance(&leaf, &source, uv) {
                    rays += 1;
                    visible += passed;
                }
            }
            visible / f64::from(MASK_RAYS)
        })
        .collect();
    let area = nodes[r].surface.area;
    let weighted: f64 = leaves
        .iter()
        .zip(&seen)
        .map(|(&i, w)| nodes[i as usize].surface.area * w)
        .sum();
    let scale: Vec<f64> = if weighted > 0.0 {
        seen.iter().map(|w| w * area / weighted).collect()
    } else {
        vec![1.0; leaves.len()]
    };
    let mut centroid = DVec3::ZERO;
    for (&i, s) in leaves.iter().zip(&scale) {
        let leaf = &nodes[i as usize].surface;
        centroid += leaf.centroid * (leaf.area * s);
    }
    (leaves, scale, centroid / area, rays)
}
