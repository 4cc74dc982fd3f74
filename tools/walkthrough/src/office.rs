//! The office floor: a grid of rooms joined by doors, lit by ceiling panels, with a desk and a
//! cabinet in every room. Metres, y up (glTF), every face an axis-aligned rectangle wound
//! counter-clockwise seen from the side that faces into the room (the baker's faces are
//! one-sided, normal = (v1 − v0) × (v2 − v0)).
//!
//! Layout: room (i, j) of an N × M floor has the clear interior x ∈ [i p, i p + s],
//! z ∈ [j p, j p + s], y ∈ [0, h], with s the room size and p = s + [`WALL`] the pitch. Walls
//! between rooms are [`WALL`] thick: one face per room, cut around a door
//! ([`DOOR_WIDTH`] × [`DOOR_HEIGHT`], centred), plus the door's reveal (two jambs, the lintel's
//! underside and a threshold that closes the floor under the doorway). Outer walls are one face
//! per room, facing in. The solid columns where walls cross have no faces: no room sees them.
//! Every room is closed apart from its doors, so light only leaves it into its neighbours.
//!
//! Coordinates are snapped to 1/1024 m, so every coordinate and every edge length is exact in
//! the f32 of the glTF file and [`Floor::elements`] predicts the mesher's count exactly.

use std::fmt;
use std::str::FromStr;

/// Wall thickness between rooms (m). Dyadic, so room corners stay exact in f32.
pub const WALL: f64 = 0.125;
/// Door opening in every wall between two rooms (m).
pub const DOOR_WIDTH: f64 = 1.0;
pub const DOOR_HEIGHT: f64 = 2.1;
/// Ceiling light panel: width (x) × length (z), and its distance below the ceiling (m).
pub const PANEL: [f64; 2] = [0.6, 1.2];
pub const PANEL_DROP: f64 = 0.05;
/// Emission of a panel (the baker's e, per band).
pub const PANEL_EMISSION: [f64; 3] = [5.0; 3];
/// Desk and cabinet boxes: footprint (long × short) and height (m).
pub const DESK: [f64; 3] = [1.4, 0.7, 0.75];
pub const CABINET: [f64; 3] = [0.8, 0.4, 1.2];
/// Gap between a cabinet and the walls of its corner (m).
pub const CABINET_GAP: f64 = 0.1;
/// Smallest room size and height the layout fits in (doors, furniture, panels).
pub const MIN_ROOM_SIZE: f64 = 3.5;
pub const MIN_HEIGHT: f64 = 2.5;

/// `N×M`: N rooms along x, M along z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rooms {
    pub x: usize,
    pub z: usize,
}

impl Rooms {
    pub fn count(self) -> usize {
        self.x * self.z
    }
}

impl fmt::Display for Rooms {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.x, self.z)
    }
}

impl FromStr for Rooms {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("rooms must look like 2x3 (N×M, each 1–256), got {s:?}");
        let (x, z) = s.split_once(['x', 'X', '×']).ok_or_else(bad)?;
        let parse = |v: &str| match v.trim().parse::<usize>() {
            Ok(n) if (1..=256).contains(&n) => Ok(n),
            _ => Err(bad()),
        };
        Ok(Rooms {
            x: parse(x)?,
            z: parse(z)?,
        })
    }
}

/// The floor's materials, in glTF material order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Surface {
    Floor,
    Wall,
    Ceiling,
    Light,
    Desk,
    Cabinet,
}

impl Surface {
    pub const ALL: [Surface; 6] = [
        Surface::Floor,
        Surface::Wall,
        Surface::Ceiling,
        Surface::Light,
        Surface::Desk,
        Surface::Cabinet,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Surface::Floor => "floor",
            Surface::Wall => "wall",
            Surface::Ceiling => "ceiling",
            Surface::Light => "light",
            Surface::Desk => "desk",
            Surface::Cabinet => "cabinet",
        }
    }

    /// Reflectance ρ per band.
    pub fn rho(self) -> [f64; 3] {
        match self {
            Surface::Floor => [0.34, 0.3, 0.26],
            Surface::Wall => [0.7; 3],
            Surface::Ceiling => [0.8; 3],
            Surface::Light => [0.0; 3],
            Surface::Desk => [0.6, 0.48, 0.36],
            Surface::Cabinet => [0.4, 0.46, 0.55],
        }
    }

    /// Emission e per band.
    pub fn emission(self) -> [f64; 3] {
        match self {
            Surface::Light => PANEL_EMISSION,
            _ => [0.0; 3],
        }
    }
}

pub type Quad = [[f64; 3]; 4];

/// One room's faces, grouped by surface (each group becomes one glTF primitive).
#[derive(Clone, Debug, PartialEq)]
pub struct Room {
    pub name: String,
    pub faces: Vec<(Surface, Vec<Quad>)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Floor {
    pub rooms: Rooms,
    pub room_size: f64,
    pub height: f64,
    pub room_list: Vec<Room>,
    /// What the scene is, for the glTF's generator line and scene name (`None`: the office
    /// floor's own).
    pub title: Option<(String, String)>,
    /// A sun: a directional light travelling along this unit direction.
    pub sun: Option<[f64; 3]>,
}

impl Floor {
    pub fn quads(&self) -> impl Iterator<Item = (Surface, &Quad)> {
        self.room_list
            .iter()
            .flat_map(|r| r.faces.iter())
            .flat_map(|(s, q)| q.iter().map(move |q| (*s, q)))
    }

    pub fn quad_count(&self) -> usize {
        self.quads().count()
    }

    /// Elements the baker's mesher makes at `--max-element-size size`: per quad
    /// ceil(|v0 v1| / size) × ceil(|v0 v3| / size) (opposite edges are equal in a rectangle).
    pub fn elements(&self, size: f64) -> u64 {
        let steps = |a: [f64; 3], b: [f64; 3]| ((distance(a, b) / size).ceil() as u64).max(1);
        self.quads()
            .map(|(_, q)| steps(q[0], q[1]) * steps(q[0], q[3]))
            .sum()
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// 1/1024 m: exact in f32 for every coordinate of a floor under 16 km.
pub(crate) fn snap(x: f64) -> f64 {
    (x * 1024.0).round() / 1024.0
}

/// An axis-aligned rectangle in the plane `axis = at`, facing `+axis` (`positive`) or `−axis`,
/// spanning `a` and `b` along the next two axes in cyclic order (x → y, z; y → z, x; z → x, y),
/// counter-clockwise seen from the side it faces.
pub(crate) fn rect(axis: usize, positive: bool, at: f64, a: [f64; 2], b: [f64; 2]) -> Quad {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let corner = |s: f64, t: f64| {
        let mut p = [0.0; 3];
        p[axis] = snap(at);
        p[u] = snap(s);
        p[v] = snap(t);
        p
    };
    let [a0, a1] = a;
    let [b0, b1] = b;
    if positive {
        [
            corner(a0, b0),
            corner(a1, b0),
            corner(a1, b1),
            corner(a0, b1),
        ]
    } else {
        [
            corner(a0, b0),
            corner(a0, b1),
            corner(a1, b1),
            corner(a1, b0),
        ]
    }
}

/// Axis indices for [`rect`].
pub(crate) const X: usize = 0;
pub(crate) const Y: usize = 1;
pub(crate) const Z: usize = 2;

/// A box standing on the floor: top and four sides facing out, no bottom.
fn open_box(x: [f64; 2], z: [f64; 2], height: f64) -> Vec<Quad> {
    let y = [0.0, height];
    vec![
        rect(Y, true, height, z, x),
        rect(X, false, x[0], y, z),
        rect(X, true, x[1], y, z),
        rect(Z, false, z[0], x, y),
        rect(Z, true, z[1], x, y),
    ]
}

/// A deterministic 64-bit mix of the room index (splitmix64's finaliser).
fn mix(i: usize, j: usize) -> u64 {
    let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_add(0x632B_E59B_D9B4_E019);
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^ (h >> 31)
}

/// The office floor. `room_size` ≥ [`MIN_ROOM_SIZE`], `height` ≥ [`MIN_HEIGHT`] (checked).
pub fn office(rooms: Rooms, room_size: f64, height: f64) -> Result<Floor, String> {
    office_with(rooms, room_size, height, false)
}

/// [`office`], or with `open_plan` an open-plan floor: the same rooms' floors, ceilings,
/// panels and furniture tiled without walls between them (outer walls only), so every part
/// of the floor sees every other — the case the cluster descent cannot cull.
pub fn office_with(
    rooms: Rooms,
    room_size: f64,
    height: f64,
    open_plan: bool,
) -> Result<Floor, String> {
    if !(room_size.is_finite() && (MIN_ROOM_SIZE..=100.0).contains(&room_size)) {
        return Err(format!(
            "--room-size must be between {MIN_ROOM_SIZE} and 100 m, got {room_size}"
        ));
    }
    if !(height.is_finite() && (MIN_HEIGHT..=room_size.max(MIN_HEIGHT)).contains(&height)) {
        return Err(format!(
            "--height must be between {MIN_HEIGHT} m and the room size, got {height}"
        ));
    }
    let (s, h) = (room_size, height);
    let pitch = if open_plan { s } else { s + WALL };
    let door = |start: f64| {
        [
            start + (s - DOOR_WIDTH) / 2.0,
            start + (s + DOOR_WIDTH) / 2.0,
        ]
    };
    let mut room_list = Vec::with_capacity(rooms.count());
    for j in 0..rooms.z {
        for i in 0..rooms.x {
            let x = [i as f64 * pitch, i as f64 * pitch + s];
            let z = [j as f64 * pitch, j as f64 * pitch + s];
            let mut floor = vec![rect(Y, true, 0.0, z, x)];
            let ceiling = vec![rect(Y, false, h, z, x)];
            let mut walls = Vec::new();

            // Room-side face of the wall in the plane axis = at, spanning `run` along the other
            // plan axis, facing into the room (`positive`); cut around a door if `doorway`.
            let mut wall_face = |axis: usize, positive: bool, at: f64, run: [f64; 2], doorway| {
                // rect's first span is the next axis cyclically: x-walls span (y, z),
                // z-walls span (x, y).
                let face = |r: [f64; 2], y: [f64; 2]| {
                    if axis == X {
                        rect(X, positive, at, y, r)
                    } else {
                        rect(Z, positive, at, r, y)
                    }
                };
                if doorway {
                    let d = door(run[0]);
                    walls.push(face([run[0], d[0]], [0.0, h]));
                    walls.push(face([d[1], run[1]], [0.0, h]));
                    walls.push(face(d, [DOOR_HEIGHT, h]));
                } else {
                    walls.push(face(run, [0.0, h]));
                }
            };
            if open_plan {
                // Outer walls only.
                if i == 0 {
                    wall_face(X, true, x[0], z, false);
                }
                if i + 1 == rooms.x {
                    wall_face(X, false, x[1], z, false);
                }
                if j == 0 {
                    wall_face(Z, true, z[0], x, false);
                }
                if j + 1 == rooms.z {
                    wall_face(Z, false, z[1], x, false);
                }
            } else {
                wall_face(X, true, x[0], z, i > 0);
                wall_face(X, false, x[1], z, i + 1 < rooms.x);
                wall_face(Z, true, z[0], x, j > 0);
                wall_face(Z, false, z[1], x, j + 1 < rooms.z);
            }

            // The reveals of the doors in this room's +x and +z walls: jambs facing into the
            // doorway, the lintel's underside, and the threshold.
            if i + 1 < rooms.x && !open_plan {
                let t = [x[1], x[1] + WALL];
                let d = door(z[0]);
                walls.push(rect(Z, true, d[0], t, [0.0, DOOR_HEIGHT]));
                walls.push(rect(Z, false, d[1], t, [0.0, DOOR_HEIGHT]));
                walls.push(rect(Y, false, DOOR_HEIGHT, d, t));
                floor.push(rect(Y, true, 0.0, d, t));
            }
            if j + 1 < rooms.z && !open_plan {
                let t = [z[1], z[1] + WALL];
                let d = door(x[0]);
                walls.push(rect(X, true, d[0], [0.0, DOOR_HEIGHT], t));
                walls.push(rect(X, false, d[1], [0.0, DOOR_HEIGHT], t));
                walls.push(rect(Y, false, DOOR_HEIGHT, t, d));
                floor.push(rect(Y, true, 0.0, t, d));
            }

            // Two panels facing down, along z, either side of the room's centre line.
            let centre = [x[0] + s / 2.0, z[0] + s / 2.0];
            let lights = [-1.0, 1.0]
                .map(|side| {
                    let cx = centre[0] + side * s / 5.0;
                    rect(
                        Y,
                        false,
                        h - PANEL_DROP,
                        [centre[1] - PANEL[1] / 2.0, centre[1] + PANEL[1] / 2.0],
                        [cx - PANEL[0] / 2.0, cx + PANEL[0] / 2.0],
                    )
                })
                .to_vec();

            // Furniture, varied per room: the cabinet in one corner (along one of its walls),
            // the desk near the centre, shifted away from the cabinet by up to 0.3 m and
            // turned by 90° in some rooms. Neither touches a wall, nor each other.
            let hash = mix(i, j);
            let corner = hash % 4;
            let (east, north) = (corner & 1 == 1, corner & 2 == 2);
            let along_x = hash >> 2 & 1 == 1;
            let [cl, cs, ch] = CABINET;
            let (cw, cd) = if along_x { (cl, cs) } else { (cs, cl) };
            let cx = if east {
                [x[1] - CABINET_GAP - cw, x[1] - CABINET_GAP]
            } else {
                [x[0] + CABINET_GAP, x[0] + CABINET_GAP + cw]
            };
            let cz = if north {
                [z[1] - CABINET_GAP - cd, z[1] - CABINET_GAP]
            } else {
                [z[0] + CABINET_GAP, z[0] + CABINET_GAP + cd]
            };
            let cabinet = open_box(cx, cz, ch);

            let shift = |bits: u64| (bits % 301) as f64 / 1000.0;
            let away = |toward_high: bool| if toward_high { -1.0 } else { 1.0 };
            let dx = away(east) * shift(hash >> 8);
            let dz = away(north) * shift(hash >> 24);
            let [dl, ds, dh] = DESK;
            let (dw, dd) = if hash >> 3 & 1 == 1 {
                (ds, dl)
            } else {
                (dl, ds)
            };
            let (mx, mz) = (centre[0] + dx, centre[1] + dz);
            let desk = open_box(
                [mx - dw / 2.0, mx + dw / 2.0],
                [mz - dd / 2.0, mz + dd / 2.0],
                dh,
            );

            let faces = vec![
                (Surface::Floor, floor),
                (Surface::Wall, walls),
                (Surface::Ceiling, ceiling),
                (Surface::Light, lights),
                (Surface::Desk, desk),
                (Surface::Cabinet, cabinet),
            ];
            room_list.push(Room {
                name: format!("room_{i}_{j}"),
                // An open plan's inner rooms have no walls: no empty primitive for them.
                faces: faces.into_iter().filter(|(_, q)| !q.is_empty()).collect(),
            });
        }
    }
    Ok(Floor {
        rooms,
        room_size,
        height,
        room_list,
        title: None,
        sun: None,
    })
}

/// Unit normal (v1 − v0) × (v2 − v0) of a quad.
pub fn normal(q: &Quad) -> [f64; 3] {
    let d = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let (u, v) = (d(q[0], q[1]), d(q[0], q[2]));
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    n.map(|x| x / len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rooms_parse() {
        assert_eq!("2x3".parse(), Ok(Rooms { x: 2, z: 3 }));
        assert_eq!("8×8".parse(), Ok(Rooms { x: 8, z: 8 }));
        for bad in ["", "2", "0x2", "2x", "axb", "2x3x4", "300x1"] {
            assert!(bad.parse::<Rooms>().is_err(), "{bad}");
        }
    }

    #[test]
    fn rect_faces_its_side() {
        for axis in 0..3 {
            for positive in [true, false] {
                let n = normal(&rect(axis, positive, 1.0, [0.0, 2.0], [0.0, 3.0]));
                let mut want = [0.0; 3];
                want[axis] = if positive { 1.0 } else { -1.0 };
                assert_eq!(n, want, "axis {axis} positive {positive}");
            }
        }
    }

    #[test]
    fn bad_sizes_are_refused() {
        let r = Rooms { x: 1, z: 1 };
        assert!(office(r, 3.0, 3.0).is_err());
        assert!(office(r, 4.0, 2.0).is_err());
        assert!(office(r, f64::NAN, 3.0).is_err());
        assert!(office(r, 4.0, 3.0).is_ok());
    }

    /// Predicted counts: per room floor 256 + ceiling 256 + panels 30 + desk 72 + cabinet 68,
    /// a wall side with a door 160 (6×12 twice + 4×4), without 192 (16×12); a door's reveal
    /// 26 (jambs 9 + 9, lintel 4, threshold 4).
    #[test]
    fn element_arithmetic() {
        let one = office(Rooms { x: 1, z: 1 }, 4.0, 3.0).unwrap();
        assert_eq!(one.elements(0.25), 256 + 256 + 30 + 72 + 68 + 4 * 192);
        let two = office(Rooms { x: 2, z: 1 }, 4.0, 3.0).unwrap();
        assert_eq!(
            two.elements(0.25),
            2 * (256 + 256 + 30 + 72 + 68 + 3 * 192 + 160) + 26
        );
    }
    #[test]
    fn an_open_plan_floor_has_outer_walls_only() {
        let rooms = Rooms { x: 3, z: 2 };
        let open = office_with(rooms, 4.0, 3.0, true).unwrap();
        let walls: Vec<&Quad> = open
            .quads()
            .filter(|(s, _)| *s == Surface::Wall)
            .map(|(_, q)| q)
            .collect();
        // One face per room along the outside: 2 × (3 + 2).
        assert_eq!(walls.len(), 10);
        // Every wall lies on the floor's outline, x ∈ {0, 12} or z ∈ {0, 8}.
        for q in walls {
            let on = |k: usize, at: f64| q.iter().all(|v| (v[k] - at).abs() < 1e-12);
            assert!(
                on(0, 0.0) || on(0, 12.0) || on(2, 0.0) || on(2, 8.0),
                "{q:?}"
            );
        }
        // Floors tile the 12 × 8 m plan without gaps: total area 96 m².
        let area: f64 = open
            .quads()
            .filter(|(s, _)| *s == Surface::Floor)
            .map(|(_, q)| distance(q[0], q[1]) * distance(q[0], q[3]))
            .sum();
        assert!((area - 96.0).abs() < 1e-9, "{area}");
    }
}
