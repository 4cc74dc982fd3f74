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
}

/// The operator over borrowed trees and entries: the final transport and the coarse solves
/// between linking passes share it.
pub(super) struct View<'a> {
    pub(super) n: usize,
    pub(super) nodes: &'a [Node],
    pub(super) children: &'a [u32],
    pub(super) entries: &'a Entries,
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
        // Gather over links, each receiver summed in its fixed entry order: the mean
        // irradiance over the node and its gradient (a linear function over the node).
        let mut g = vec![Delivered::<B>::default(); total];
        g.par_chunks_mut(1024).enumerate().for_each(|(chunk, out)| {
            for (k, gr) in out.iter_mut().enumerate() {
                let r = chunk * 1024 + k;
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
                for ((&s, &f), grad) in self.entries.sources[lo..hi]
                    .iter()
                    .zip(&self.entries.coefficients[lo..hi])
                    .zip(&self.entries.gradients[lo..hi])
                {
                    let s = s as usize;
                    let xs = &xn[s];
                    for (mean, x) in d.mean.iter_mut().zip(xs) {
                        *mean += f * x;
                    }
                    if s >= self.n {
                        let source = vec3(grad[1]) * inverse_area;
                        for (mean, m) in d.mean.iter_mut().zip(&moment[s]) {
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
                *gr = d;
            }
        });
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
pub(super) fn assemble(nodes: &[Node], links: &[Link]) -> Entries {
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
    for l in links() {
        // The gradient was fitted to the unoccluded kernel: scale it by the visible fraction.
        let visible = if l.g0 > 0.0 { (l.g / l.g0) as f32 } else { 0.0 };
        for (side, (r, s)) in [(l.p, l.q), (l.q, l.p)].into_iter().enumerate() {
            let k = fill[r as usize] as usize;
            let area = nodes[r as usize].surface.area;
            sources[k] = s;
            coefficients[k] = l.g / area;
            gradients[k] = [
                l.gradient[side].map(|v| v * visible),
                l.gradient[1 - side].map(|v| v * visible),
            ];
            fill[r as usize] += 1;
        }
    }
    Entries {
        offsets,
        sources,
        coefficients,
        gradients,
    }
}
