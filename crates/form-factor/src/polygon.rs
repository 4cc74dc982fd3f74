//! The clipping buffer: up to [`CAPACITY`] vertices in place (no allocation per element pair),
//! what clipping a [`scene::Convex`] against a plane leaves. A working space, not a polygon
//! value: surfaces are `scene::Convex` ([`crate::Surface`] derefs to one).

use glam::DVec3;
use mesher::{Element, ElementMesh, PatchGrid};

/// A clipped quad has at most 5 vertices; keep room for 8.
pub(crate) const CAPACITY: usize = 8;

#[derive(Clone, Copy, Debug)]
pub struct Poly {
    v: [DVec3; CAPACITY],
    n: usize,
}

impl Poly {
    pub fn from_points(points: impl IntoIterator<Item = DVec3>) -> Poly {
        let mut p = Poly {
            v: [DVec3::ZERO; CAPACITY],
            n: 0,
        };
        for x in points.into_iter().take(CAPACITY) {
            p.v[p.n] = x;
            p.n += 1;
        }
        p
    }

    pub fn len(&self) -> usize {
        self.n
    }

    pub fn vertex(&self, k: usize) -> DVec3 {
        self.v[k]
    }

    pub fn vertices(&self) -> &[DVec3] {
        &self.v[..self.n]
    }

    /// Largest distance from the first vertex (a size scale for tolerances).
    pub fn extent(&self) -> f64 {
        self.v[..self.n]
            .iter()
            .map(|x| x.distance(self.v[0]))
            .fold(0.0, f64::max)
    }

    /// Moves the polygon into the frame with this origin and unit length.
    pub fn move_to_frame(&mut self, origin: DVec3, unit: f64) {
        for x in &mut self.v[..self.n] {
            *x = (*x - origin) / unit;
        }
    }

    /// Cuts the polygon to its part in front of the plane through `point` with normal
    /// `normal` (signed distance > `tol`; in place: pairs are screened by the million) and
    /// says whether anything was cut off. `None` (the polygon unchanged) when nothing of it
    /// lies in front (behind or in the plane).
    pub fn clip_front(&mut self, point: DVec3, normal: DVec3, tol: f64) -> Option<bool> {
        let mut dist = [0.0f64; CAPACITY];
        let (mut front, mut back) = (0, 0);
        for (d, x) in dist.iter_mut().zip(&self.v[..self.n]) {
            *d = (*x - point).dot(normal);
            if *d > tol {
                front += 1;
            } else if *d < -tol {
                back += 1;
            }
        }
        if front == 0 {
            return None;
        }
        if back == 0 {
            return Some(false);
        }
        // Sutherland–Hodgman against one plane; vertices within `tol` count as on it.
        let mut out = Poly {
            v: [DVec3::ZERO; CAPACITY],
            n: 0,
        };
        for k in 0..self.n {
            let l = (k + 1) % self.n;
            let (a, b, da, db) = (self.v[k], self.v[l], dist[k], dist[l]);
            if da >= -tol {
                out.push(a);
            }
            if (da > tol && db < -tol) || (da < -tol && db > tol) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        *self = out;
        Some(true)
    }

    fn push(&mut self, x: DVec3) {
        if self.n < CAPACITY {
            self.v[self.n] = x;
            self.n += 1;
        }
    }
}

/// A mesh of two single-element polygons (3 or 4 vertices each), for [`crate::polygon_pair`].
pub fn two_element_mesh(a: &[DVec3], b: &[DVec3]) -> ElementMesh {
    let mut mesh = ElementMesh::default();
    for (k, poly) in [a, b].into_iter().enumerate() {
        let base = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(poly);
        let sides = poly.len().min(4);
        let mut corners = [base; 4];
        for (c, slot) in corners.iter_mut().enumerate() {
            *slot = base + c.min(sides - 1) as u32;
        }
        // Newell normal (about the first vertex: raw coordinates far from the origin would
        // cancel catastrophically), area and centroid by a fan.
        let mut normal = DVec3::ZERO;
        for i in 0..sides {
            normal += (poly[i] - poly[0]).cross(poly[(i + 1) % sides] - poly[0]);
        }
        let normal = normal.normalize();
        let mut area = 0.0;
        let mut moment = DVec3::ZERO;
        for i in 1..sides - 1 {
            let t = (poly[i] - poly[0]).cross(poly[i + 1] - poly[0]).dot(normal) * 0.5;
            area += t;
            moment += (poly[0] + poly[i] + poly[i + 1]) * (t / 3.0);
        }
        mesh.elements.push(Element {
            polygon: k as u32,
            corners,
            sides: sides as u8,
            area,
            centroid: moment / area,
            normal,
        });
        mesh.patches.push(PatchGrid {
            vertices: base..base + sides as u32,
            elements: k as u32..k as u32 + 1,
        });
    }
    mesh
}
