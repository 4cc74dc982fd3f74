//! Cluster culling: the descent of the cluster tree over polygon roots that leaves the
//! polygon pairs to link and drops cluster pairs every shadow ray finds blocked.

use super::*;

/// The cluster tree over the polygon roots and what its descent needs per pass.
pub(super) struct Culling<'a> {
    pub(super) clusters: Clusters,
    pub(super) roots: &'a [u32],
    /// Per polygon: its root's surface and its index among the occluders.
    pub(super) surfaces: Vec<Surface>,
    pub(super) polygon: Vec<u32>,
    /// Per cluster: the elements of its polygons.
    pub(super) elements: Vec<u64>,
}

/// A cluster pair dropped because every shadow ray between it was blocked, with the rays it
/// was tested with (into `a`, into `b`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Dropped {
    pub(super) a: u32,
    pub(super) b: u32,
    pub(super) rays: [u32; 2],
}

/// What a descent produced.
#[derive(Default)]
pub(super) struct Descent {
    pub(super) links: Vec<Link>,
    pub(super) dropped: Vec<Dropped>,
}

impl Descent {
    pub(super) fn append(&mut self, mut other: Descent) {
        self.links.append(&mut other.links);
        self.dropped.append(&mut other.dropped);
    }
}

/// Runs `first` then `second` into `out`: in parallel (each into its own part, appended in
/// order, so the result does not depend on the thread count) when `parallel`.
pub(super) fn both<F, G>(parallel: bool, out: &mut Descent, first: F, second: G)
where
    F: FnOnce(&mut Descent) + Send,
    G: FnOnce(&mut Descent) + Send,
{
    if parallel {
        // The first part straight into `out`: only the second part's links are moved.
        let ((), y) = rayon::join(
            || first(out),
            || {
                let mut o = Descent::default();
                second(&mut o);
                o
            },
        );
        out.append(y);
    } else {
        first(out);
        second(out);
    }
}

/// Cluster pairs with more polygons than this (product of the two counts) are descended in
/// parallel.
pub(super) const PARALLEL_PAIRS: u64 = 4096;

/// Node pairs spanning more element pairs than this are refined in parallel tasks (a task
/// of this size takes milliseconds, far above rayon's cost per task; larger tasks would
/// move fewer links between lists but balance worse on two polygons).
pub(super) const PARALLEL_ELEMENT_PAIRS: u64 = 1 << 16;

impl<'a> Culling<'a> {
    pub(super) fn new(nodes: &[Node], roots: &'a [u32], leaves: &[u64]) -> Culling<'a> {
        let surfaces: Vec<Surface> = roots.iter().map(|&r| nodes[r as usize].surface).collect();
        let polygon = roots.iter().map(|&r| nodes[r as usize].polygon).collect();
        let clusters = Clusters::new(&surfaces);
        let elements = clusters
            .nodes
            .iter()
            .map(|c| {
                clusters.order[c.first as usize..(c.first + c.count) as usize]
                    .iter()
                    .map(|&k| leaves[roots[k as usize] as usize])
                    .sum()
            })
            .collect();
        Culling {
            clusters,
            roots,
            surfaces,
            polygon,
            elements,
        }
    }

    pub(super) fn weights(&self, linker: &Linker) -> Weights {
        let b: Vec<f64> = self.roots.iter().map(|&r| linker.b[r as usize]).collect();
        let rho: Vec<f64> = self.roots.iter().map(|&r| linker.rho[r as usize]).collect();
        Weights::new(&self.clusters, &self.surfaces, &b, &rho)
    }

    /// Whether every ray of the pair (`rays` per direction) is blocked.
    pub(super) fn blocked(
        &self,
        linker: &Linker,
        weights: &Weights,
        a: u32,
        b: u32,
        rays: [u32; 2],
    ) -> bool {
        for (k, (receiver, source)) in [(a, b), (b, a)].into_iter().enumerate() {
            if rays[k] == 0 {
                continue;
            }
            let (blocked, cast) = clusters::all_blocked(
                &self.clusters,
                weights,
                &self.surfaces,
                &self.polygon,
                linker.occluders,
                receiver,
                source,
                rays[k],
                k as u64,
            );
            linker
                .counters
                .rays_cast
                .fetch_add(u64::from(cast), Ordering::Relaxed);
            if !blocked {
                return false;
            }
        }
        true
    }

    /// Links cluster `a` with cluster `b` (`a == b`: the cluster with itself) into `out`.
    pub(super) fn descend(
        &self,
        linker: &Linker,
        weights: &Weights,
        a: u32,
        b: u32,
        progress: &(dyn Fn(LinkProgress) + Sync),
        out: &mut Descent,
    ) {
        let nodes = &self.clusters.nodes;
        let (ca, cb) = (nodes[a as usize], nodes[b as usize]);
        let large = u64::from(ca.count) * u64::from(cb.count) > PARALLEL_PAIRS
            || self.elements[a as usize] * self.elements[b as usize] > PARALLEL_ELEMENT_PAIRS;
        if a == b {
            let Some([l, r]) = ca.children else {
                progress(LinkProgress::Polygons(1));
                return;
            };
            both(
                large,
                out,
                |o| {
                    self.descend(linker, weights, l, l, progress, o);
                    self.descend(linker, weights, r, r, progress, o);
                },
                |o| self.descend(linker, weights, l, r, progress, o),
            );
            return;
        }
        let Some((split, other)) = self.split(a, b) else {
            // Two polygons: linked as HSA91 links them.
            let order = &self.clusters.order;
            let (p, q) = (order[ca.first as usize], order[cb.first as usize]);
            let (p, q) = (p.min(q), p.max(q));
            linker
                .counters
                .polygon_pairs
                .fetch_add(1, Ordering::Relaxed);
            linker.link(
                self.roots[p as usize],
                self.roots[q as usize],
                true,
                &mut out.links,
            );
            return;
        };
        let distance = clusters::box_distance(&ca, &cb);
        if let Some(rays) = clusters::rays_needed(weights, a, b, distance, linker.epsilon) {
            if self.blocked(linker, weights, a, b, rays) {
                linker
                    .counters
                    .clusters_dropped
                    .fetch_add(1, Ordering::Relaxed);
                out.dropped.push(Dropped { a, b, rays });
                return;
            }
        }
        let [l, r] = split;
        both(
            large,
            out,
            |o| self.descend(linker, weights, l, other, progress, o),
            |o| self.descend(linker, weights, r, other, progress, o),
        );
    }

    /// Which cluster of a disjoint pair to split (the one with the larger box, of those with
    /// children) and the other; `None` for two single polygons.
    pub(super) fn split(&self, a: u32, b: u32) -> Option<([u32; 2], u32)> {
        let (ca, cb) = (
            &self.clusters.nodes[a as usize],
            &self.clusters.nodes[b as usize],
        );
        match (ca.children, cb.children) {
            (None, None) => None,
            (Some(x), None) => Some((x, b)),
            (None, Some(y)) => Some((y, a)),
            (Some(x), Some(y)) => {
                if (ca.hi - ca.lo).length_squared() >= (cb.hi - cb.lo).length_squared() {
                    Some((x, b))
                } else {
                    Some((y, a))
                }
            }
        }
    }

    /// The first pass: the root cluster with itself.
    pub(super) fn initial(
        &self,
        linker: &Linker,
        progress: &(dyn Fn(LinkProgress) + Sync),
    ) -> Descent {
        let mut out = Descent::default();
        if !self.clusters.nodes.is_empty() {
            let weights = self.weights(linker);
            self.descend(linker, &weights, 0, 0, progress, &mut out);
        }
        out
    }

    /// A later pass: the dropped pairs whose missed light, with this pass's radiosities,
    /// needs more rays than they were tested with are tested again and, if a ray arrives,
    /// descended. Returns the pairs still dropped and the new links.
    pub(super) fn revisit(&self, linker: &Linker, dropped: &[Dropped]) -> Descent {
        let weights = self.weights(linker);
        let nodes = &self.clusters.nodes;
        let none = |_: LinkProgress| {};
        let parts: Vec<Descent> = dropped
            .par_iter()
            .map(|d| {
                let (ca, cb) = (nodes[d.a as usize], nodes[d.b as usize]);
                let distance = clusters::box_distance(&ca, &cb);
                let mut out = Descent::default();
                match clusters::rays_needed(&weights, d.a, d.b, distance, linker.epsilon) {
                    Some(rays) if rays[0] <= d.rays[0] && rays[1] <= d.rays[1] => {
                        out.dropped.push(*d);
                    }
                    Some(rays) if self.blocked(linker, &weights, d.a, d.b, rays) => {
                        out.dropped.push(Dropped { rays, ..*d });
                    }
                    _ => {
                        // Only pairs with a cluster of several polygons are dropped.
                        if let Some((split, other)) = self.split(d.a, d.b) {
                            for c in split {
                                self.descend(linker, &weights, c, other, &none, &mut out);
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut out = Descent::default();
        for p in parts {
            out.append(p);
        }
        out
    }
}
