//! The operator: receiver-ordered entries assembled from the links, and `y = F x` with
//! push–pull through the trees.

use super::*;

/// Operator entries by receiver node: `sources[offsets[r]..offsets[r + 1]]` with the
/// coefficients `F_rs` in `coefficients`.
pub(super) struct Entries {
    pub(super) offsets: Vec<u64>,
    pub(super) sources: Vec<u32>,
    pub(super) coefficients: Vec<f64>,
    /// Per entry, the visible part of: `∇F_{dx→s}` over the receiver r (the linear part of
    /// the irradiance it delivers, pushed down as a linear function), and `∇F_{dy→r}` over
    /// the source s (dotted with the first moment of the source's radiosity and divided by
    /// `A_r`: the kernel's linear variation over the source, HSA91's constant source made
    /// linear). The same f32 values serve both directions of a link, so the operator stays
    /// exactly reciprocal.
    pub(super) gradients: Vec<[[f32; 3]; 2]>,
    /// Per entry: whether its light goes through the masks of its interior ends
    /// ([`masks::masked`]); all false when the operator has no masks (the coarse solves).
    pub(super) masked: Vec<bool>,
    /// Per entry: the kernel's relative variation that the link's linear model leaves over
    /// the receiver and over the source (the links' `residual`, receiver first; 0 over an
    /// element), and the standard deviation of the coefficient that its shadow rays leave,
    /// relative to the coefficient (the link's `visibility_sd` over its visible fraction),
    /// for the error estimate ([`HierarchicalTransport::link_error`]).
    pub(super) residuals: Vec<[f32; 3]>,
}

/// The operator over borrowed trees and entries: the final transport and the coarse solves
/// between linking passes share it.
pub(super) struct View<'a> {
    pub(super) n: usize,
    pub(super) nodes: &'a [Node],
    pub(super) children: &'a [u32],
    pub(super) entries: &'a Entries,
    pub(super) masks: &'a Masks,
    pub(super) accuracy: f64,
}

impl View<'_> {
    /// `y = F x` for `B` bands at once (B = 1 or 3), the same bits per band either way.
    pub(super) fn apply_generic<const B: usize>(&self, x: &[[f64; B]], y: &mut [[f64; B]]) {
        let total = self.nodes.len();
        // Pull: leaves are the elements; interior nodes (created after their children) are
        // area-weighted means of their children, with the first moment `∫ x (y − c) dy` of
        // the piecewise-constant x about the node's centroid c (0 for an element).
        let mut xn = vec![[0.0; B]; total];
        let mut moment = vec![[DVec3::ZERO; B]; total];
        xn[..self.n].copy_from_slice(&x[..self.n]);
        for u in self.n..total {
            let node = &self.nodes[u];
            let mut sum = [0.0; B];
            let mut m = [DVec3::ZERO; B];
            for &c in &self.children[node.first as usize..(node.first + node.count) as usize] {
                let child = &self.nodes[c as usize].surface;
                let offset = child.centroid - node.surface.centroid;
                for band in 0..B {
                    let power = child.area * xn[c as usize][band];
                    sum[band] += power;
                    m[band] += moment[c as usize][band] + offset * power;
                }
            }
            for band in 0..B {
                xn[u][band] = sum[band] / node.surface.area;
            }
            moment[u] = m;
        }
        // Masked nodes as sources: means and first moments weighted by their masks' scales
        // (about the weighted centroid), so that an element sends where it receives from.
        let masks = self.masks;
        let weighted: Vec<([f64; B], [DVec3; B])> = (0..masks.node.len())
            .into_par_iter()
            .map(|m| {
                let area = self.nodes[masks.node[m] as usize].surface.area;
                let centre = masks.centroid[m];
                let (mut mean, mut moment) = ([0.0; B], [DVec3::ZERO; B]);
                for k in masks.range(m) {
                    let leaf = &self.nodes[masks.leaves[k] as usize].surface;
                    let weight = leaf.area * masks.scale[k];
                    let offset = leaf.centroid - centre;
                    for band in 0..B {
                        let power = weight * x[masks.leaves[k] as usize][band];
                        mean[band] += power;
                        moment[band] += offset * power;
                    }
                }
                (mean.map(|v| v / area), moment)
            })
            .collect();
        let source = |s: usize, masked: bool| -> (&[f64; B], &[DVec3; B]) {
            match masks.of_node[s] {
                m if masked && m != NONE => {
                    let (mean, moment) = &weighted[m as usize];
                    (mean, moment)
                }
                _ => (&xn[s], &moment[s]),
            }
        };
        // What the entries `lo..hi` of receiver r deliver: the mean irradiance over the node
        // and its gradient (a linear function over the node), summed in entry order; `take`
        // picks the entries: all (`None`), or those whose masked flag is the given one.
        let deliver = |r: usize, take: Option<bool>| -> Delivered<B> {
            let (lo, hi) = (
                self.entries.offsets[r] as usize,
                self.entries.offsets[r + 1] as usize,
            );
            let mut d = Delivered::<B>::default();
            // An element's irradiance gradient is never pushed further, and an element
            // as a source has no first moment: the common element–element entries
            // take the constant term alone.
            let receiver_is_leaf = r < self.n;
            let inverse_area = 1.0 / self.nodes[r].surface.area;
            for k in lo..hi {
                let masked = self.entries.masked[k];
                if take.is_some_and(|t| t != masked) {
                    continue;
                }
                let (s, f, grad) = (
                    self.entries.sources[k] as usize,
                    self.entries.coefficients[k],
                    &self.entries.gradients[k],
                );
                let (xs, ms) = source(s, masked);
                for (mean, x) in d.mean.iter_mut().zip(xs) {
                    *mean += f * x;
                }
                if s >= self.n {
                    let source = vec3(grad[1]) * inverse_area;
                    for (mean, m) in d.mean.iter_mut().zip(ms) {
                        *mean += source.dot(*m);
                    }
                }
                if !receiver_is_leaf {
                    let receiver = vec3(grad[0]);
                    for (gradient, x) in d.gradient.iter_mut().zip(xs) {
                        *gradient += receiver * *x;
                    }
                }
            }
            d
        };
        // Gather over links: an element takes every entry, a node those that are not masked
        // (its masked ones are gathered per mask below).
        let mut g = vec![Delivered::<B>::default(); total];
        g.par_chunks_mut(1024).enumerate().for_each(|(chunk, out)| {
            for (k, gr) in out.iter_mut().enumerate() {
                let r = chunk * 1024 + k;
                *gr = deliver(r, (r >= self.n).then_some(false));
            }
        });
        let shadowed: Vec<Delivered<B>> = (0..masks.node.len())
            .into_par_iter()
            .map(|m| deliver(masks.node[m] as usize, Some(true)))
            .collect();
        // Push: parents before children (reverse creation order). A child receives the
        // parent's linear function averaged over itself, i.e. its value at the child's area
        // centroid; the children's area-weighted mean is the parent's mean exactly (their
        // centroids average to the parent's), so energy is unchanged.
        for u in (self.n..total).rev() {
            let node = self.nodes[u];
            let gu = g[u];
            for &c in &self.children[node.first as usize..(node.first + node.count) as usize] {
                let offset = self.nodes[c as usize].surface.centroid - node.surface.centroid;
                let gc = &mut g[c as usize];
                for band in 0..B {
                    gc.mean[band] += gu.mean[band] + gu.gradient[band].dot(offset);
                    gc.gradient[band] += gu.gradient[band];
                }
            }
        }
        // A mask's light straight to its elements, scaled: the linear function about the
        // weighted centroid times s_i, whose a_i-weighted sum is the node's total (masks.rs).
        for (m, d) in shadowed.iter().enumerate() {
            let centre = masks.centroid[m];
            for k in masks.range(m) {
                let i = masks.leaves[k] as usize;
                let offset = self.nodes[i].surface.centroid - centre;
                let scale = masks.scale[k];
                for band in 0..B {
                    g[i].mean[band] += scale * (d.mean[band] + d.gradient[band].dot(offset));
                }
            }
        }
        for (yk, gk) in y[..self.n].iter_mut().zip(&g[..self.n]) {
            *yk = gk.mean;
        }
    }
}

pub(super) fn vec3(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

/// What the links deliver to one node: mean irradiance and its gradient per band.
#[derive(Clone, Copy, Debug)]
pub(super) struct Delivered<const B: usize> {
    pub(super) mean: [f64; B],
    pub(super) gradient: [DVec3; B],
}

impl<const B: usize> Default for Delivered<B> {
    fn default() -> Self {
        Delivered {
            mean: [0.0; B],
            gradient: [DVec3::ZERO; B],
        }
    }
}

impl Operator for View<'_> {
    fn n(&self) -> usize {
        self.n
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let xs: Vec<[f64; 1]> = x.iter().map(|&v| [v]).collect();
        let mut ys = vec![[0.0; 1]; self.n];
        self.apply_generic(&xs, &mut ys);
        for (yi, v) in y.iter_mut().zip(ys) {
            *yi = v[0];
        }
    }

    fn apply_bands(&self, x: &[[f64; BANDS]], y: &mut [[f64; BANDS]]) {
        self.apply_generic(x, y);
    }

    fn accuracy(&self) -> f64 {
        self.accuracy
    }

    /// Elements get their ancestors' link averages: single rows may exceed 1 by the links'
    /// receiver error (area-weighted sums are exact), which is not integration error.
    fn rows_bounded(&self) -> bool {
        false
    }
}

/// The operator's receiver-ordered entries from the links (both directions of each).
/// With `masks`, the entries of [`masks::masked`] links are flagged for the masks.
pub(super) fn assemble(nodes: &[Node], links: &[Link], masks: bool) -> Entries {
    let total = nodes.len();
    let mut counts = vec![0u64; total + 1];
    // Blocked links (every ray stopped) carry nothing: they stay in the link list, where a
    // later pass may refine them, but not in the operator.
    let links = || links.iter().filter(|l| l.g != 0.0);
    for l in links() {
        counts[l.p as usize + 1] += 1;
        counts[l.q as usize + 1] += 1;
    }
    for k in 0..total {
        counts[k + 1] += counts[k];
    }
    let offsets = counts;
    let entries = offsets[total] as usize;
    let mut fill: Vec<u64> = offsets[..total].to_vec();
    let mut sources = vec![0u32; entries];
    let mut coefficients = vec![0.0f64; entries];
    let mut gradients = vec![[[0.0f32; 3]; 2]; entries];
    let mut masked = vec![false; entries];
    let mut residuals = vec![[0.0f32; 3]; entries];
    for l in links() {
        // The gradient was fitted to the unoccluded kernel: scale it by the visible fraction.
        let visible = if l.g0 > 0.0 { (l.g / l.g0) as f32 } else { 0.0 };
        // The visible fraction's deviation relative to the coefficient g = g0 × fraction.
        let deviation = if visible > 0.0 {
            l.visibility_sd / visible
        } else {
            0.0
        };
        for (side, (r, s)) in [(l.p, l.q), (l.q, l.p)].into_iter().enumerate() {
            let k = fill[r as usize] as usize;
            let area = nodes[r as usize].surface.area;
            sources[k] = s;
            coefficients[k] = l.g / area;
            gradients[k] = [
                l.gradient[side].map(|v| v * visible),
                l.gradient[1 - side].map(|v| v * visible),
            ];
            masked[k] = masks && masks::masked(l);
            residuals[k] = [l.residual[side], l.residual[1 - side], deviation].map(|v| v.max(0.0));
            fill[r as usize] += 1;
        }
    }
    Entries {
        offsets,
        sources,
        coefficients,
        gradients,
        masked,
        residuals,
    }
}
