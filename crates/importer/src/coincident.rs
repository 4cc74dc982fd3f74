//! Coincident faces across meshes: a polygon with the same corners, in the same cyclic order
//! (so facing the same way), as an earlier polygon of the scene is dropped, the first kept.
//!
//! Real files stack copies: a prop pasted twice at the same place, a floor exported with the
//! room and again on its own, the overlapping solids of MGF scenes. Two coincident faces that
//! face the same way are both seen in full from everywhere (neither hides the other), so
//! every element that sees them counts their form factor twice and light is created (eq. 15's
//! Σ_j F_ij ≤ 1 fails). Duplicates inside one primitive are dropped earlier, per instance
//! (`polygon::drop_duplicates`); this pass compares polygons of different primitives and
//! nodes. Opposite-facing coincident faces are a thin two-sided sheet and both kept.
//! Coplanar faces that only partly overlap are not cut here: the dense transport scales the
//! rows they push past 1 (`form_factor::DenseFormFactors::limit_row_sums`).
//!
//! Not a mesh repair tool: no T-junction or overlap clipping, no winding changes.

use crate::{Polygon, Scene};
use std::collections::hash_map::{Entry, HashMap};

/// Corners closer than this × the scene size are the same corner (the importer's tolerance
/// for repeated vertices).
const SAME_CORNER: f64 = 1e-9;

/// A polygon's corners on the grid of [`SAME_CORNER`] × scene size, rotated to start at the
/// smallest (the cyclic order, hence the facing, is kept).
type Key = Vec<[i64; 3]>;

fn key(polygon: &Polygon, cell: f64) -> Option<Key> {
    let mut corners: Vec<[i64; 3]> = Vec::with_capacity(polygon.vertices.len());
    for v in &polygon.vertices {
        let q = (*v / cell).round();
        // Beyond ±2^62 cells the grid is meaningless: no key, never dropped.
        if !q.is_finite() || q.abs().max_element() > 4.6e18 {
            return None;
        }
        corners.push([q.x as i64, q.y as i64, q.z as i64]);
    }
    let start = (0..corners.len()).min_by_key(|&k| corners[k])?;
    corners.rotate_left(start);
    Some(corners)
}

/// Drops every polygon that coincides with an earlier one facing the same way (see the
/// module docs), with its texture mapping; counts them in
/// [`crate::ImportStats::coincident_dropped`] and adds one warning naming the first pair.
pub(crate) fn drop_coincident(scene: &mut Scene) {
    let (lo, hi) = crate::bounds(&scene.polygons);
    let size = (hi - lo).length();
    if !(size.is_finite() && size > 0.0) {
        return;
    }
    let cell = SAME_CORNER * size;
    let mut first: HashMap<Key, usize> = HashMap::with_capacity(scene.polygons.len());
    let mut keep = vec![true; scene.polygons.len()];
    let mut example = None;
    for (k, polygon) in scene.polygons.iter().enumerate() {
        let Some(key) = key(polygon, cell) else {
            continue;
        };
        match first.entry(key) {
            Entry::Vacant(slot) => {
                slot.insert(k);
            }
            Entry::Occupied(earlier) => {
                keep[k] = false;
                example.get_or_insert((k, *earlier.get()));
            }
        }
    }
    let dropped = keep.iter().filter(|&&k| !k).count();
    let Some((later, earlier)) = example else {
        return;
    };
    let describe = |k: usize| {
        let origin = scene.polygons[k].origin;
        let mesh = scene
            .layout
            .meshes
            .get(origin.mesh)
            .and_then(|m| m.name.as_deref());
        format!(
            "{} face {}",
            crate::describe("mesh", mesh, origin.mesh),
            origin.face
        )
    };
    let (faces, verb) = if dropped == 1 {
        ("face coincides", "was")
    } else {
        ("faces coincide", "were")
    };
    scene.warnings.push(format!(
        "{dropped} {faces} with an earlier face facing the same way (same corners) and {verb} \
         dropped, the first kept: both would be seen in full, counting their light twice \
         (e.g. {} duplicates {})",
        describe(later),
        describe(earlier)
    ));
    scene.stats.coincident_dropped += dropped;
    let mut flags = keep.iter();
    scene.polygons.retain(|_| flags.next() == Some(&true));
    if scene.uvs.len() == keep.len() {
        let mut flags = keep.iter();
        scene.uvs.retain(|_| flags.next() == Some(&true));
    }
}

/// Whether two corner lists are the same polygon facing the same way, as this module decides
/// (for tests).
#[cfg(test)]
fn same(a: &[glam::DVec3], b: &[glam::DVec3], cell: f64) -> bool {
    let polygon = |v: &[glam::DVec3]| Polygon {
        vertices: v.to_vec(),
        normal: glam::DVec3::Z,
        material: 0,
        origin: crate::Origin {
            node: 0,
            mesh: 0,
            primitive: 0,
            face: 0,
            side: crate::Side::Front,
        },
    };
    key(&polygon(a), cell) == key(&polygon(b), cell)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn rotations_match_and_reversals_do_not() {
        let quad = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let mut rotated = quad;
        rotated.rotate_left(2);
        let mut reversed = quad;
        reversed.reverse();
        assert!(same(&quad, &rotated, 1e-9));
        assert!(!same(&quad, &reversed, 1e-9));
        let moved: Vec<DVec3> = quad.iter().map(|v| *v + DVec3::X * 1e-3).collect();
        assert!(!same(&quad, &moved, 1e-9));
    }
}
