//! An open atrium (issues 33 and 35): a square courtyard open to the sky, ringed on every
//! storey by a gallery whose inner edge is a colonnade of round columns, under one sun — the
//! open scene where most surfaces see each other, as in Crytek Sponza. Metres, y up (glTF),
//! every face a planar rectangle wound counter-clockwise seen from the side it faces.
//!
//! Layout: the courtyard's clear interior is x, z ∈ [−c/2, c/2] (c = `courtyard`), open from
//! the ground to the sky. Each of the `storeys` storeys (height `storey`) has a gallery ring
//! `gallery` deep around it: its floor (facing up; on the ground storey the courtyard's floor
//! too), its ceiling (the slab above, [`SLAB`] thick, facing down), its back walls (facing
//! in), and the slab's edge facing the courtyard. Columns of radius [`COLUMN_RADIUS`] stand
//! every `pitch` metres along the gallery's inner edge, each a prism of `facets` sides cut
//! into `segments` bands (the polygon count is theirs: 4 (c / pitch) storeys × facets ×
//! segments). The roof over the top gallery faces the sky. Outer façades are left out: no
//! point inside sees them.
//!
//! Coordinates are snapped to 1/1024 m (exact in f32), as the office floor's.

use crate::office::{normal, rect, snap, Floor, Quad, Room, Rooms, Surface, X, Y, Z};

/// Slab thickness between storeys (m).
pub const SLAB: f64 = 0.25;
/// Column radius (m), and the columns' distance behind the gallery's inner edge (m).
pub const COLUMN_RADIUS: f64 = 0.3;
pub const COLUMN_SETBACK: f64 = 0.5;

/// The atrium's dimensions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Atrium {
    pub courtyard: f64,
    pub gallery: f64,
    pub storeys: usize,
    pub storey: f64,
    pub pitch: f64,
    pub facets: usize,
    pub segments: usize,
}

impl Default for Atrium {
    /// About 164 000 polygons: a 24 m courtyard, 4 storeys of 4 m, 4 m galleries, columns
    /// every 3 m of 32 facets × 40 bands.
    fn default() -> Self {
        Atrium {
            courtyard: 24.0,
            gallery: 4.0,
            storeys: 4,
            storey: 4.0,
            pitch: 3.0,
            facets: 32,
            segments: 40,
        }
    }
}

/// The sun's direction of travel: from the south-east, 60° above the horizon.
pub const SUN: [f64; 3] = [
    -0.353_553_390_593_273_8,
    -0.866_025_403_784_438_6,
    -0.353_553_390_593_273_8,
];

/// The atrium as a [`Floor`] (one "room" per storey), with its sun.
pub fn atrium(a: &Atrium) -> Result<Floor, String> {
    let sane = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
    if !sane(a.courtyard, 4.0, 400.0) || !sane(a.gallery, 2.0, 50.0) || !sane(a.storey, 2.5, 20.0) {
        return Err("courtyard 4–400 m, gallery 2–50 m and storey height 2.5–20 m".into());
    }
    if !(1..=64).contains(&a.storeys)
        || !sane(a.pitch, 2.0 * COLUMN_RADIUS + 0.5, a.courtyard)
        || !(3..=256).contains(&a.facets)
        || !(1..=256).contains(&a.segments)
    {
        return Err(
            "1–64 storeys, a column pitch of 1.1 m up to the courtyard, 3–256 facets, 1–256 segments"
                .into(),
        );
    }
    let (c, r) = (a.courtyard / 2.0, a.courtyard / 2.0 + a.gallery);
    let mut room_list = Vec::with_capacity(a.storeys);
    for k in 0..a.storeys {
        let y0 = k as f64 * a.storey;
        let y1 = y0 + a.storey - SLAB;
        let mut floor = ring(Y, true, y0, c, r);
        if k == 0 {
            floor.push(rect(Y, true, 0.0, [-c, c], [-c, c]));
        }
        let ceiling = ring(Y, false, y1, c, r);
        let mut walls = vec![
            rect(X, true, -r, [y0, y1], [-r, r]),
            rect(X, false, r, [y0, y1], [-r, r]),
            rect(Z, true, -r, [-r, r], [y0, y1]),
            rect(Z, false, r, [-r, r], [y0, y1]),
        ];
        // The edge of the slab above, facing the courtyard.
        let (e0, e1) = (y1, y1 + SLAB);
        walls.extend([
            rect(X, true, -c, [e0, e1], [-c, c]),
            rect(X, false, c, [e0, e1], [-c, c]),
            rect(Z, true, -c, [-c, c], [e0, e1]),
            rect(Z, false, c, [-c, c], [e0, e1]),
        ]);
        let mut columns = Vec::new();
        let count = ((a.courtyard / a.pitch).floor() as usize).max(1);
        let spacing = a.courtyard / count as f64;
        let offset = c + COLUMN_SETBACK;
        for i in 0..count {
            let t = -c + spacing * (i as f64 + 0.5);
            for centre in [[t, -offset], [t, offset], [-offset, t], [offset, t]] {
                column(centre, y0, y1, a.facets, a.segments, &mut columns);
            }
        }
        walls.extend(columns);
        let mut faces = vec![
            (Surface::Floor, floor),
            (Surface::Wall, walls),
            (Surface::Ceiling, ceiling),
        ];
        if k + 1 == a.storeys {
            faces.push((Surface::Ceiling, ring(Y, true, y1 + SLAB, c, r)));
        }
        room_list.push(Room {
            name: format!("storey-{k}"),
            faces,
        });
    }
    Ok(Floor {
        rooms: Rooms {
            x: a.storeys,
            z: 1,
        },
        room_size: a.courtyard,
        height: a.storey,
        room_list,
        title: Some((
            format!(
                "atrium, {} m courtyard, {} storeys of {} m, {} m galleries, columns every {} m of {} × {} faces",
                a.courtyard, a.storeys, a.storey, a.gallery, a.pitch, a.facets, a.segments
            ),
            format!("atrium-{}x{}", a.courtyard, a.storeys),
        )),
        sun: Some(SUN),
    })
}

/// The square ring between half-widths `c` and `r` in the plane y = `at`, as four
/// rectangles, facing up (`up`) or down.
fn ring(axis: usize, up: bool, at: f64, c: f64, r: f64) -> Vec<Quad> {
    // rect(Y, …) spans z then x.
    vec![
        rect(axis, up, at, [c, r], [-r, r]),
        rect(axis, up, at, [-r, -c], [-r, r]),
        rect(axis, up, at, [-c, c], [c, r]),
        rect(axis, up, at, [-c, c], [-r, -c]),
    ]
}

/// A column: a prism of `facets` sides around the vertical axis through `centre` (x, z),
/// from `y0` to `y1` in `segments` bands, each face facing out.
fn column(centre: [f64; 2], y0: f64, y1: f64, facets: usize, segments: usize, out: &mut Vec<Quad>) {
    let at = |f: usize| {
        let angle = std::f64::consts::TAU * f as f64 / facets as f64;
        [
            snap(centre[0] + COLUMN_RADIUS * angle.cos()),
            snap(centre[1] + COLUMN_RADIUS * angle.sin()),
        ]
    };
    for s in 0..segments {
        let ya = snap(y0 + (y1 - y0) * s as f64 / segments as f64);
        let yb = snap(y0 + (y1 - y0) * (s + 1) as f64 / segments as f64);
        for f in 0..facets {
            let (p, q) = (at(f), at(f + 1));
            let face = [
                [p[0], ya, p[1]],
                [q[0], ya, q[1]],
                [q[0], yb, q[1]],
                [p[0], yb, p[1]],
            ];
            // Wound so that its normal points away from the axis.
            let n = normal(&face);
            let out_x = (p[0] + q[0]) / 2.0 - centre[0];
            let out_z = (p[1] + q[1]) / 2.0 - centre[1];
            if n[0] * out_x + n[2] * out_z > 0.0 {
                out.push(face);
            } else {
                out.push([face[0], face[3], face[2], face[1]]);
            }
        }
    }
}
