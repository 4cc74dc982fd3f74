//! Linking: BF refinement of node pairs into the links that carry light (HSA91 §4), with
//! their visibility and error estimate.

use super::*;

/// Links whose whole unoccluded error contribution is below this × ε get one shadow ray.
pub(super) const FAINT: f64 = 1.0 / 16.0;

/// The uncertainty of the visible fraction of a pair whose every one of `rays` shadow rays
/// was blocked: the open share the rays can have missed, by the "rule of three" (with n rays
/// all blocked, a visible share above 3/n would have been seen with 95% probability; the rays
/// are stratified, so the bound is conservative).
pub(super) fn blocked_uncertainty(rays: u32) -> f64 {
    (3.0 / f64::from(rays.max(1))).min(1.0)
}

/// A kept link between nodes p and q.
#[derive(Clone, Copy, Debug)]
pub(super) struct Link {
    pub(super) p: u32,
    pub(super) q: u32,
    /// `A_p F_pq`, visible part.
    pub(super) g: f64,
    /// `G₀ · uncertainty` (the visibility's share of the BF criterion's error factor, the same
    /// for both receivers; the fit's share is computed from `g` and `residual`).
    pub(super) k: f64,
    /// Whether some polygon can come between p and q (children must test again).
    pub(super) occludable: bool,
    /// Unoccluded `A_p F_pq`, for recomputing `g` and `k` once the shadow rays are cast.
    pub(super) g0: f64,
    /// Per node (p, then q): the relative variation of the kernel over it that the link
    /// cannot represent (the linear fit's residual; 0 for an element).
    pub(super) residual: [f32; 2],
    /// Per receiver (p, then q): the gradient of the unoccluded point-to-node kernel over it
    /// (world units, in its plane), the linear part of what the link delivers.
    pub(super) gradient: [[f32; 3]; 2],
    pub(super) clipped: bool,
    /// Whether every shadow ray of the pair was blocked when it was screened (its visible
    /// fraction is 0 and no more rays are cast for it).
    pub(super) blocked: bool,
    /// Whether `g` is the estimator's value with its visible fraction (only links that are
    /// kept are integrated and get rays; until then `g0` is the screen's rough value).
    pub(super) final_value: bool,
    /// The standard deviation of the visible fraction its shadow rays estimated (0 where
    /// nothing can occlude; [`visibility_sd`]), for the error estimate.
    pub(super) visibility_sd: f32,
}

/// The standard deviation of a visible fraction estimated from `rays` stratified shadow rays
/// that found `fraction`: where a shadow boundary crosses the pair (0 < fraction < 1), that
/// of jittered sampling of an indicator with a smooth boundary in the pair's 4-D domain,
/// about `1 / (2 K^{5/8})` (the dense transport's visibility estimate, `bake::error`); where
/// every ray agreed, the share the rays can have missed ([`blocked_uncertainty`]). A clipped
/// pair (a node straddling the other's plane) pushes its light to all of the node: half of it
/// may be behind.
pub(super) fn visibility_sd(rays: u32, fraction: f64, clipped: bool) -> f32 {
    let sampled = if rays == 0 {
        0.0
    } else if fraction > 0.0 && fraction < 1.0 {
        0.5 / f64::from(rays).powf(0.625)
    } else {
        blocked_uncertainty(rays)
    };
    let clip = if clipped { 0.5 } else { 0.0 };
    sampled.max(clip) as f32
}

/// What the linking of one pass needs.
pub(super) struct Linker<'a> {
    pub(super) nodes: &'a [Node],
    pub(super) children: &'a [u32],
    pub(super) occluders: &'a Occluders,
    pub(super) options: &'a HierarchicalOptions,
    /// Per node: max over bands of ρ, and of the current radiosity estimate.
    pub(super) rho: &'a [f64],
    pub(super) b: &'a [f64],
    /// Per node: how much that estimate varies over it (max − min over its elements).
    pub(super) spread: &'a [f64],
    /// Per node: its elements (leaves), for deciding which pairs are worth a parallel task.
    pub(super) leaves: &'a [u64],
    pub(super) epsilon: f64,
    pub(super) counters: &'a Counters,
}

impl Linker<'_> {
    /// Links nodes p and q (a candidate pair not yet evaluated): appends the kept links of
    /// the pair and, where it refines, of its children. `occludable`: whether the parent pair
    /// could be occluded (children of an unoccludable pair cannot be).
    pub(super) fn link(&self, p: u32, q: u32, occludable: bool, out: &mut Vec<Link>) {
        let (np, nq) = (&self.nodes[p as usize], &self.nodes[q as usize]);
        if np.polygon == nq.polygon {
            return;
        }
        // An element's own variation does not matter: it receives the exact average over
        // itself, and as a source its radiosity is constant. (The screen is made here and
        // borrowed below: it holds the clipped pair, too large to move around per pair.)
        let Some(screen) = surface_screen(&np.surface, &nq.surface, [np.count > 0, nq.count > 0])
        else {
            return;
        };
        let link = self.evaluate(p, q, occludable, &screen);
        // Kept if it meets the tolerance or cannot be split, else its split is linked.
        match self.split(&link) {
            None => out.push(self.finalize(link, &screen)),
            Some(split) => self.link_split(&link, split, out),
        }
    }

    /// Links the children of the split node with the other node of `link`.
    pub(super) fn link_split(
        &self,
        link: &Link,
        (parent, other, parent_is_p): (u32, u32, bool),
        out: &mut Vec<Link>,
    ) {
        let node = &self.nodes[parent as usize];
        let kids = &self.children[node.first as usize..(node.first + node.count) as usize];
        let pair = |c: u32| if parent_is_p { (c, other) } else { (other, c) };
        // A large pair (two big polygons facing each other) is worth parallel tasks: each
        // half into its own list, appended in order, so the links do not depend on threads.
        let work = self.leaves[parent as usize] * self.leaves[other as usize];
        if work > PARALLEL_ELEMENT_PAIRS && kids.len() >= 2 {
            let (first, rest) = kids.split_at(kids.len() / 2);
            let run = |part: &[u32], o: &mut Vec<Link>| {
                for &c in part {
                    let (a, b) = pair(c);
                    self.link(a, b, link.occludable, o);
                }
            };
            // The first half straight into `out`: only the second half's links are moved.
            let ((), mut y) = rayon::join(
                || run(first, out),
                || {
                    let mut o = Vec::new();
                    run(rest, &mut o);
                    o
                },
            );
            out.append(&mut y);
            return;
        }
        for &c in kids {
            let (a, b) = pair(c);
            self.link(a, b, link.occludable, out);
        }
    }

    /// `link` with its value from the form-factor estimator and, if it is occludable, its
    /// visible fraction from shadow rays (done once, when a link is first kept). Links whose
    /// whole unoccluded contribution is within a quarter of the tolerance get at most 9 rays,
    /// within [`FAINT`] of it one: their visibility hardly matters.
    pub(super) fn finalize(&self, mut link: Link, screen: &PairScreen) -> Link {
        if link.final_value {
            return link;
        }
        let (np, nq) = (&self.nodes[link.p as usize], &self.nodes[link.q as usize]);
        let options = self.options;
        let c = self.counters;
        {
            let pair = screened_pair(
                screen,
                &np.surface,
                &nq.surface,
                &options.contour,
                options.estimator,
            );
            c.kernel_evaluations
                .fetch_add(pair.evaluations, Ordering::Relaxed);
            let method = match pair.method {
                Method::Contour => 0,
                Method::PointPolygon => 1,
                Method::PointPoint => 2,
            };
            c.by_method[method].fetch_add(1, Ordering::Relaxed);
            if link.blocked && link.g0 > 0.0 {
                // k was the screen's rough value times the rays' uncertainty.
                link.k *= pair.value / link.g0;
            }
            link.g0 = pair.value;
        }
        let mut fraction = 1.0;
        let mut rays = 0;
        if link.blocked {
            fraction = 0.0;
        } else if link.occludable {
            let importance = (self.rho[link.p as usize] * self.b[link.q as usize]
                / np.surface.area)
                .max(self.rho[link.q as usize] * self.b[link.p as usize] / nq.surface.area)
                * link.g0;
            if importance < FAINT * self.epsilon {
                // A faint link (most pairs of distant rooms): one ray between the centroids,
                // lifted off both surfaces, decides all or nothing (or glass's share).
                let lift = self.occluders.ray_offset();
                let (a, b) = (np.surface, nq.surface);
                fraction = self.occluders.segment_transmittance(
                    a.centroid + a.normal * lift,
                    b.centroid + b.normal * lift,
                    [np.polygon as usize, nq.polygon as usize],
                );
                c.rays_cast.fetch_add(1, Ordering::Relaxed);
                rays = 1;
            } else {
                let samples = if importance < 0.25 * self.epsilon {
                    options.samples.min(9)
                } else {
                    options.samples
                };
                let v = self.occluders.visibility(
                    &patch(np),
                    &patch(nq),
                    samples,
                    pair_seed(link.p as usize, link.q as usize),
                );
                c.rays_cast.fetch_add(u64::from(v.rays), Ordering::Relaxed);
                rays = v.rays;
                fraction = v.fraction;
            }
        }
        link.g = link.g0 * fraction;
        link.visibility_sd = visibility_sd(rays, fraction, link.clipped);
        // Occludable: a shadow boundary may cross the pair even where every ray of the
        // sample arrived (a few rays per node miss small occluders).
        if !link.blocked {
            let uncertainty = if link.occludable || link.clipped {
                1.0
            } else {
                0.0
            };
            link.k = link.g0 * uncertainty;
        }
        link.final_value = true;
        link
    }

    /// A kept link re-examined with new radiosities: `None` if it stays, else its refinement.
    pub(super) fn refine_kept(&self, link: &Link) -> Option<Vec<Link>> {
        let split = self.split(link)?;
        let mut out = Vec::new();
        self.link_split(link, split, &mut out);
        Some(out)
    }

    /// The BF error of a link between p and q of value `g`, visibility error factor `k` and
    /// kernel residuals `residual` (over p, over q): the larger over its two receivers r
    /// (source s) of `ρ_r (B_s (g residual_r + k) + ΔB_s g residual_s) / A_r`.
    pub(super) fn error(&self, p: u32, q: u32, g: f64, k: f64, residual: [f32; 2]) -> f64 {
        let (p, q) = (p as usize, q as usize);
        let [rp, rq] = residual.map(f64::from);
        let at = |r: usize, s: usize, rr: f64, rs: f64| {
            self.rho[r] * (self.b[s] * (g * rr + k) + self.spread[s] * g * rs)
                / self.nodes[r].surface.area
        };
        at(p, q, rp, rq).max(at(q, p, rq, rp))
    }

    /// Whether both receivers' error is within ε.
    pub(super) fn acceptable(&self, link: &Link) -> bool {
        let error = self.error(link.p, link.q, link.g, link.k, link.residual);
        error <= self.epsilon || error.is_nan()
    }

    /// Which node to split (HSA91: the larger), with the other and whether the split one is
    /// `p`; `None` when the link meets the tolerance or both ends are elements.
    pub(super) fn split(&self, link: &Link) -> Option<(u32, u32, bool)> {
        let (np, nq) = (&self.nodes[link.p as usize], &self.nodes[link.q as usize]);
        if self.acceptable(link) {
            return None;
        }
        let (split_p, split_q) = (np.count > 0, nq.count > 0);
        match (split_p, split_q) {
            (false, false) => None,
            (true, false) => Some((link.p, link.q, true)),
            (false, true) => Some((link.q, link.p, false)),
            (true, true) if np.surface.area >= nq.surface.area => Some((link.p, link.q, true)),
            (true, true) => Some((link.q, link.p, false)),
        }
    }

    /// The pair's rough value, error factor and visibility from its `screen` (the pair can
    /// exchange light: [`Linker::link`] checked); occludable pairs that only visibility would
    /// refine get their shadow rays here and become blocked links when every ray is stopped.
    pub(super) fn evaluate(
        &self,
        p: u32,
        q: u32,
        parent_occludable: bool,
        screen: &PairScreen,
    ) -> Link {
        let (np, nq) = (&self.nodes[p as usize], &self.nodes[q as usize]);
        let c = self.counters;
        c.pairs_evaluated.fetch_add(1, Ordering::Relaxed);
        // A node straddling the other's plane was clipped to its front part, but the link
        // pushes its light to all of the node: as uncertain as a shadow boundary.
        let clipped = screen.kind == PairKind::Clipped;
        let mut occludable = false;
        // A pair that would be kept even if it were fully uncertain gets rays without the
        // occludability test: the test would only save its few rays, and far pairs (most of
        // the polygon pairs of a large scene) are nearly always occludable.
        // For both receivers: what a linear model of the kernel misses over the receiver and over
        // the source (B may vary over the source as much as B itself: the conservative
        // assumption).
        let [sp, sq] = screen.sides;
        let residual = [sp.residual as f32, sq.residual as f32];
        let g = screen.rough;
        let worst = self.error(p, q, g, g, residual);
        if parent_occludable && worst <= self.epsilon {
            occludable = true;
        } else if parent_occludable {
            c.pairs_tested.fetch_add(1, Ordering::Relaxed);
            if self.occluders.can_occlude(&patch(np), &patch(nq)) {
                occludable = true;
                c.pairs_occludable.fetch_add(1, Ordering::Relaxed);
            }
        }
        // Until rays say otherwise (they are cast only if the link is kept), an occludable
        // link is fully visible and fully uncertain: the largest error it can have.
        let uncertainty = if clipped || occludable { 1.0 } else { 0.0 };
        let gradient = [sp.gradient, sq.gradient].map(|v| v.as_vec3().to_array());
        let mut link = Link {
            p,
            q,
            g,
            k: g * uncertainty,
            occludable,
            clipped,
            blocked: false,
            g0: g,
            residual,
            gradient,
            final_value: false,
            visibility_sd: 0.0,
        };
        // A pair that the uncertainty of its visibility alone would refine gets its shadow
        // rays now: when every ray is blocked (two rooms with a wall between them) its visible
        // fraction is 0 and what the rays can have missed is small, so it is kept as a
        // blocked link instead of being refined down to elements.
        if occludable
            && !clipped
            && !self.acceptable(&link)
            && self.error(p, q, g, 0.0, residual) <= self.epsilon
        {
            let v = self.occluders.visibility(
                &patch(np),
                &patch(nq),
                self.options.samples,
                pair_seed(p as usize, q as usize),
            );
            c.rays_cast.fetch_add(u64::from(v.rays), Ordering::Relaxed);
            // Kept at value 0 only when what the rays can have missed is negligible (within
            // FAINT × ε, as a faint link's single ray): a pair is kept blocked exactly when
            // all its rays are stopped, and refined (its children find the gaps) when one
            // arrives, so a blocked link's missed light is a one-sided loss, and within ε
            // per link it summed to 0.39% of the emitted power on a 2 × 2 office floor
            // (docs/accuracy.md). Otherwise the pair stays fully uncertain and refines.
            let k = g * blocked_uncertainty(v.rays);
            if v.fraction == 0.0
                && v.rays > 0
                && self.error(p, q, 0.0, k, residual) <= FAINT * self.epsilon
            {
                link.blocked = true;
                link.g = 0.0;
                link.k = k;
            }
        }
        link
    }
}
