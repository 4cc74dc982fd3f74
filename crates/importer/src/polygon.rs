//! Geometry cleaning: world-space source faces → planar convex polygons of 3 or 4 vertices.
//!
//! Per primitive instance, in this order:
//! 1. non-finite positions are an error;
//! 2. repeated consecutive vertices are removed, and faces left with < 3 vertices or zero
//!    area are dropped (one summary warning per instance);
//! 3. a face with the same vertices in the same cyclic order as an earlier face of the
//!    instance is dropped (for a double-sided material, in either order: its back side is
//!    already a surface); faces wound against their neighbours are counted (one warning)
//!    and kept as authored;
//! 4. each face becomes pieces: a triangle stays a triangle; a planar convex quad stays a
//!    quad; a concave quad is split along its inner diagonal; a non-planar quad is split
//!    into two triangles (warning); a polygon with > 4 vertices is ear-clipped and its
//!    triangles merged pairwise back into quads where they form planar convex ones;
//! 5. consecutive source triangles (faces t and t+1) that share an edge, lie in one plane
//!    and form a strictly convex quad are merged into that quad; then source triangles
//!    still single are paired the same way with a later one across any shared edge
//!    (greedily in face order: encoders that reorder triangles leave a quad's halves apart);
//! 6. the normal is computed with Newell's method from the (counter-clockwise) vertices,
//!    and double-sided materials get a reversed back polygon right after each front one.
//!
//! The callers hand in faces already counter-clockwise seen from the front in world space
//! (a mirroring node transform has been undone by reversing the vertex order).

use crate::{ImportError, ImportStats, Origin, Polygon, Side};
use glam::DVec3;
use std::collections::{HashMap, HashSet};

/// Positions closer than this × scene size are the same point.
const SAME_POINT: f64 = 1e-9;
/// A face with area ≤ this × (scene size)² has no area.
const ZERO_AREA: f64 = 1e-12;
/// A polygon is planar when every vertex lies within this × its size of its mean plane.
const PLANAR: f64 = 1e-6;
/// A corner turns left (convex) when |e1 × e2|·n exceeds this × |e1||e2| (the sine of the
/// turning angle); it is reflex when that is below minus this.
const TURN: f64 = 1e-9;

/// The most source faces a scene may have, summed over every instance: a memory guard
/// (each face is placed in world space per instance before cleaning), far above what the
/// solver can take (a mesh used by many nodes multiplies its faces).
pub(crate) const MAX_SCENE_FACES: usize = 1 << 22;

/// Adds `more` faces to the running `total`, refusing a scene over [`MAX_SCENE_FACES`].
pub(crate) fn count_faces(total: &mut usize, more: usize) -> Result<(), ImportError> {
    *total = total.saturating_add(more);
    if *total > MAX_SCENE_FACES {
        return Err(ImportError::TooLarge(format!(
            "the scene has more than {MAX_SCENE_FACES} faces (counting each instance of a \
             mesh), the importer's limit"
        )));
    }
    Ok(())
}

/// One source face (a triangle after strip/fan decoding, or an OBJ face), world space.
#[derive(Clone, Debug)]
pub(crate) struct SourceFace {
    /// Index of the face within its primitive.
    pub face: usize,
    /// Counter-clockwise seen from the front.
    pub vertices: Vec<DVec3>,
}

/// One primitive placed by one node: everything needed to turn its faces into polygons.
#[derive(Clone, Debug)]
pub(crate) struct Instance {
    /// Names the mesh and primitive in messages, e.g. `mesh "Cube" (0), primitive 0`.
    pub label: String,
    /// Names the node in messages, e.g. ` in node "Box" (3)`; empty when there is one node.
    pub place: String,
    /// Node, mesh and primitive of every polygon (`face` and `side` are set per polygon).
    pub origin: Origin,
    /// Index into the scene's materials.
    pub material: usize,
    pub double_sided: bool,
    pub faces: Vec<SourceFace>,
}

/// Length and area tolerances, relative to the scene size.
#[derive(Clone, Copy, Debug)]
struct Tolerance {
    same_point: f64,
    zero_area: f64,
}

/// What happened to one instance's faces, summarised in one warning line each.
#[derive(Default)]
struct Report {
    degenerate: usize,
    duplicates: usize,
    against_winding: usize,
    non_planar: usize,
    self_intersecting: usize,
}

/// A source face after step 2: ≥ 3 distinct consecutive vertices and non-zero area.
struct CleanFace {
    face: usize,
    vertices: Vec<DVec3>,
}

/// A cleaned piece of a face: a triangle or a convex quad.
struct Piece {
    face: usize,
    vertices: Vec<DVec3>,
    /// An untouched source triangle, which may merge with the next source triangle.
    source_triangle: bool,
}

/// Turns every instance's faces into polygons (the module's steps 1 to 6).
pub(crate) fn bake(
    instances: &[Instance],
    stats: &mut ImportStats,
    warnings: &mut Vec<String>,
) -> Result<Vec<Polygon>, ImportError> {
    check_finite(instances)?;
    let size = scene_size(instances);
    let tol = Tolerance {
        same_point: SAME_POINT * size,
        zero_area: ZERO_AREA * size * size,
    };
    let mut polygons = Vec::new();
    for instance in instances {
        bake_instance(instance, tol, stats, warnings, &mut polygons);
    }
    Ok(polygons)
}

/// Step 1: every vertex position must be a finite number.
fn check_finite(instances: &[Instance]) -> Result<(), ImportError> {
    for instance in instances {
        for face in &instance.faces {
            if !face.vertices.iter().all(|v| v.is_finite()) {
                return Err(ImportError::InvalidValue {
                    what: format!("{}, face {}{}", instance.label, face.face, instance.place),
                    problem: "vertex position is not finite".into(),
                });
            }
        }
    }
    Ok(())
}

/// The diagonal of the bounding box of every vertex (0 for an empty scene).
fn scene_size(instances: &[Instance]) -> f64 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for v in instances
        .iter()
        .flat_map(|i| &i.faces)
        .flat_map(|f| &f.vertices)
    {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if lo.x <= hi.x {
        (hi - lo).length()
    } else {
        0.0
    }
}

/// Steps 2 to 6 for one instance.
fn bake_instance(
    instance: &Instance,
    tol: Tolerance,
    stats: &mut ImportStats,
    warnings: &mut Vec<String>,
    out: &mut Vec<Polygon>,
) {
    stats.faces_read += instance.faces.len();
    let mut report = Report::default();
    let faces = clean_faces(&instance.faces, tol, &mut report);
    let faces = drop_duplicates(faces, instance.double_sided, &mut report);
    if !instance.double_sided {
        report.against_winding = against_winding(&faces);
    }
    let mut pieces = Vec::new();
    for face in faces {
        split_face(
            face.face,
            face.vertices,
            tol,
            stats,
            &mut report,
            &mut pieces,
        );
    }
    let (pieces, merged) = merge_pairs(pieces, tol, |a, b| {
        a.source_triangle && b.source_triangle && a.face + 1 == b.face
    });
    let (pieces, paired) = pair_by_edges(pieces, tol);
    stats.quads_merged += merged + paired;
    stats.degenerate_dropped += report.degenerate;
    stats.duplicates_dropped += report.duplicates;
    stats.against_winding += report.against_winding;
    for piece in pieces {
        emit(instance, piece, out);
    }
    summarise(instance, &report, warnings);
}

/// One warning line per kind of change, per instance.
fn summarise(instance: &Instance, report: &Report, warnings: &mut Vec<String>) {
    let name = format!("{}{}", instance.label, instance.place);
    if report.degenerate > 0 {
        warnings.push(format!(
            "{name}: dropped {} degenerate face(s) (repeated vertices or zero area)",
            report.degenerate
        ));
    }
    if report.duplicates > 0 {
        warnings.push(format!(
            "{name}: dropped {} duplicate face(s) (the same vertices as an earlier face, \
             which would count the surface twice)",
            report.duplicates
        ));
    }
    if report.against_winding > 0 {
        warnings.push(format!(
            "{name}: {} face(s) wound opposite to their neighbours, kept as authored \
             (they face the other way; flip them or make the material doubleSided)",
            report.against_winding
        ));
    }
    if report.non_planar > 0 {
        warnings.push(format!(
            "{name}: split {} non-planar face(s) into triangles",
            report.non_planar
        ));
    }
    if report.self_intersecting > 0 {
        warnings.push(format!(
            "{name}: {} self-intersecting face(s) split into triangles as given",
            report.self_intersecting
        ));
    }
}

/// Step 6: the front polygon, and for double-sided materials the back one right after it.
fn emit(instance: &Instance, piece: Piece, out: &mut Vec<Polygon>) {
    let normal = newell(&piece.vertices).normalize_or_zero();
    if normal == DVec3::ZERO {
        return;
    }
    let origin = Origin {
        face: piece.face,
        side: Side::Front,
        ..instance.origin
    };
    let front = Polygon {
        vertices: piece.vertices,
        normal,
        material: instance.material,
        origin,
    };
    let back = instance.double_sided.then(|| Polygon {
        vertices: front.vertices.iter().rev().copied().collect(),
        normal: -normal,
        material: instance.material,
        origin: Origin {
            side: Side::Back,
            ..origin
        },
    });
    out.push(front);
    out.extend(back);
}

/// Step 2: each face without its repeated vertices; faces left with < 3 vertices or no
/// area are counted and dropped.
fn clean_faces(faces: &[SourceFace], tol: Tolerance, report: &mut Report) -> Vec<CleanFace> {
    let mut clean = Vec::with_capacity(faces.len());
    for face in faces {
        let vertices = remove_repeats(&face.vertices, tol.same_point);
        if vertices.len() < 3 || area(&vertices) <= tol.zero_area {
            report.degenerate += 1;
        } else {
            clean.push(CleanFace {
                face: face.face,
                vertices,
            });
        }
    }
    clean
}

/// A position's exact identity: its bits, with −0 taken as +0. Coincident vertices of a
/// mesh are copies of one value, so no tolerance is needed to match them.
type PointKey = [u64; 3];

fn point_key(p: DVec3) -> PointKey {
    (p + DVec3::ZERO).to_array().map(f64::to_bits)
}

/// Step 3: keeps the first of faces with the same vertices in the same cyclic order (any
/// starting vertex); for a double-sided material also in the reverse order.
fn drop_duplicates(
    faces: Vec<CleanFace>,
    double_sided: bool,
    report: &mut Report,
) -> Vec<CleanFace> {
    let mut seen: HashSet<Vec<PointKey>> = HashSet::with_capacity(faces.len());
    let mut kept = Vec::with_capacity(faces.len());
    for face in faces {
        let keys: Vec<PointKey> = face.vertices.iter().map(|&p| point_key(p)).collect();
        let mut key = cyclic_key(&keys);
        if double_sided {
            let reversed: Vec<PointKey> = keys.iter().rev().copied().collect();
            key = key.min(cyclic_key(&reversed));
        }
        if seen.insert(key) {
            kept.push(face);
        } else {
            report.duplicates += 1;
        }
    }
    kept
}

/// The smallest rotation of a cyclic sequence: equal for every starting point.
fn cyclic_key(keys: &[PointKey]) -> Vec<PointKey> {
    let n = keys.len();
    let rotation = |start: usize| (0..n).map(move |k| keys[(start + k) % n]);
    let Some(&least) = keys.iter().min() else {
        return Vec::new();
    };
    let start = (0..n)
        .filter(|&i| keys[i] == least)
        .min_by(|&a, &b| rotation(a).cmp(rotation(b)))
        .unwrap_or(0);
    rotation(start).collect()
}

/// Step 3: how many faces are wound against their neighbours. Two faces sharing an edge
/// (an edge used by exactly these two faces, vertices matched exactly) agree when they
/// traverse it in opposite directions. Within each connected set of faces, the faces
/// that would have to be flipped to agree with the majority are counted.
fn against_winding(faces: &[CleanFace]) -> usize {
    let neighbours = edge_neighbours(faces);
    let mut parity: Vec<Option<bool>> = vec![None; faces.len()];
    let mut count = 0;
    for seed in 0..faces.len() {
        if parity[seed].is_some() {
            continue;
        }
        parity[seed] = Some(false);
        let (mut agree, mut flipped) = (0usize, 0usize);
        let mut stack = vec![seed];
        while let Some(f) = stack.pop() {
            let flip = parity[f].unwrap_or(false);
            if flip {
                flipped += 1;
            } else {
                agree += 1;
            }
            for &(g, same_direction) in &neighbours[f] {
                if parity[g].is_none() {
                    parity[g] = Some(flip ^ same_direction);
                    stack.push(g);
                }
            }
        }
        count += agree.min(flipped);
    }
    count
}

/// For each face, its neighbours across manifold edges (edges used by exactly two faces),
/// and whether the neighbour traverses the shared edge in the same direction.
fn edge_neighbours(faces: &[CleanFace]) -> Vec<Vec<(usize, bool)>> {
    let mut ids: HashMap<PointKey, u32> = HashMap::new();
    // Undirected edge → its uses (face, traversed from the lower id to the higher).
    let mut uses: HashMap<(u32, u32), Vec<(usize, bool)>> = HashMap::new();
    for (f, face) in faces.iter().enumerate() {
        let face_ids: Vec<u32> = face
            .vertices
            .iter()
            .map(|&p| {
                let next = ids.len() as u32;
                *ids.entry(point_key(p)).or_insert(next)
            })
            .collect();
        let n = face_ids.len();
        for i in 0..n {
            let (a, b) = (face_ids[i], face_ids[(i + 1) % n]);
            if a != b {
                let entry = uses.entry((a.min(b), a.max(b))).or_default();
                if entry.len() < 3 {
                    entry.push((f, a < b));
                }
            }
        }
    }
    let mut neighbours = vec![Vec::new(); faces.len()];
    for edge in uses.values() {
        if let [(f, f_up), (g, g_up)] = edge[..] {
            if f != g {
                neighbours[f].push((g, f_up == g_up));
                neighbours[g].push((f, f_up == g_up));
            }
        }
    }
    neighbours
}

/// Step 2: drops each vertex equal (within `eps`) to the one before it, cyclically.
fn remove_repeats(vertices: &[DVec3], eps: f64) -> Vec<DVec3> {
    let mut kept: Vec<DVec3> = Vec::with_capacity(vertices.len());
    for &v in vertices {
        if kept.last().is_none_or(|last| last.distance(v) > eps) {
            kept.push(v);
        }
    }
    while kept.len() > 1 && kept[0].distance(kept[kept.len() - 1]) <= eps {
        kept.pop();
    }
    kept
}

/// Step 4: one clean face (≥ 3 distinct vertices, non-zero area) into pieces.
fn split_face(
    face: usize,
    vertices: Vec<DVec3>,
    tol: Tolerance,
    stats: &mut ImportStats,
    report: &mut Report,
    pieces: &mut Vec<Piece>,
) {
    match vertices.len() {
        3 => pieces.push(Piece {
            face,
            vertices,
            source_triangle: true,
        }),
        4 => split_quad(face, &vertices, tol, report, pieces),
        _ => {
            stats.ngons_split += 1;
            if !is_planar(&vertices) {
                report.non_planar += 1;
            }
            let triangles = ear_clip(face, &vertices, tol, report);
            let (merged, _) = merge_pairs(triangles, tol, |_, _| true);
            pieces.extend(merged);
        }
    }
}

/// A planar convex quad is kept; a concave one is cut along the diagonal from its reflex
/// corner (which lies inside); a non-planar one is cut into two triangles.
fn split_quad(
    face: usize,
    v: &[DVec3],
    tol: Tolerance,
    report: &mut Report,
    pieces: &mut Vec<Piece>,
) {
    let normal = newell(v).normalize_or_zero();
    let reflex: Vec<usize> = (0..4).filter(|&i| turn(v, i, normal) < -TURN).collect();
    let planar = is_planar(v);
    if planar && reflex.is_empty() {
        pieces.push(Piece {
            face,
            vertices: v.to_vec(),
            source_triangle: false,
        });
        return;
    }
    if !planar {
        report.non_planar += 1;
    }
    // A simple quad has at most one reflex corner; two or more means the edges cross.
    let r = match reflex.as_slice() {
        [] => 0,
        [r] => *r,
        _ => {
            report.self_intersecting += 1;
            0
        }
    };
    let corner = |k: usize| v[(r + k) % 4];
    for triangle in [
        [corner(0), corner(1), corner(2)],
        [corner(0), corner(2), corner(3)],
    ] {
        if area(&triangle) > tol.zero_area {
            pieces.push(Piece {
                face,
                vertices: triangle.to_vec(),
                source_triangle: false,
            });
        }
    }
}

/// Ear clipping of a polygon with > 4 vertices, about its Newell normal. For a convex
/// polygon this is the fan from vertex 0. Falls back to a fan (counted as self-intersecting)
/// when no ear is left, which only happens for self-intersecting input.
fn ear_clip(face: usize, v: &[DVec3], tol: Tolerance, report: &mut Report) -> Vec<Piece> {
    let normal = newell(v).normalize_or_zero();
    let mut ring: Vec<usize> = (0..v.len()).collect();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    while ring.len() > 3 {
        let m = ring.len();
        // Start at corner 1 so that a convex polygon gives the fan 0-1-2, 0-2-3, ...
        let ear = (1..=m).map(|k| k % m).find(|&k| {
            let (a, b, c) = (ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]);
            is_ear(v, &ring, [a, b, c], normal)
        });
        match ear {
            Some(k) => {
                triangles.push([ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]]);
                ring.remove(k);
            }
            None => {
                report.self_intersecting += 1;
                triangles.extend((1..m - 1).map(|k| [ring[0], ring[k], ring[k + 1]]));
                ring.clear();
            }
        }
    }
    if let [a, b, c] = ring[..] {
        triangles.push([a, b, c]);
    }
    triangles
        .into_iter()
        .map(|[a, b, c]| vec![v[a], v[b], v[c]])
        .filter(|t| area(t) > tol.zero_area)
        .map(|vertices| Piece {
            face,
            vertices,
            source_triangle: false,
        })
        .collect()
}

/// A corner b (between a and c) is an ear when it turns left and no other vertex of the
/// ring lies inside or on the triangle a-b-c.
fn is_ear(v: &[DVec3], ring: &[usize], [a, b, c]: [usize; 3], normal: DVec3) -> bool {
    let (pa, pb, pc) = (v[a], v[b], v[c]);
    if turn(&[pa, pb, pc], 1, normal) <= TURN {
        return false;
    }
    let inside = |p: DVec3| {
        [(pa, pb), (pb, pc), (pc, pa)]
            .iter()
            .all(|&(s, e)| (e - s).cross(p - s).dot(normal) >= 0.0)
    };
    ring.iter()
        .filter(|&&i| i != a && i != b && i != c)
        .map(|&i| v[i])
        .filter(|&p| p != pa && p != pb && p != pc)
        .all(|p| !inside(p))
}

/// Step 5: merges consecutive triangle pieces allowed by `may_pair` into convex quads.
/// Returns the pieces and how many pairs were merged.
fn merge_pairs(
    pieces: Vec<Piece>,
    tol: Tolerance,
    may_pair: impl Fn(&Piece, &Piece) -> bool,
) -> (Vec<Piece>, usize) {
    let mut out: Vec<Piece> = Vec::with_capacity(pieces.len());
    let mut merged = 0;
    let mut iter = pieces.into_iter().peekable();
    while let Some(piece) = iter.next() {
        let quad = iter.peek().and_then(|next| {
            let both_triangles = piece.vertices.len() == 3 && next.vertices.len() == 3;
            if both_triangles && may_pair(&piece, next) {
                merge_triangles(&piece.vertices, &next.vertices, tol.same_point)
            } else {
                None
            }
        });
        match quad {
            Some(vertices) => {
                iter.next();
                merged += 1;
                out.push(Piece {
                    face: piece.face,
                    vertices,
                    source_triangle: false,
                });
            }
            None => out.push(piece),
        }
    }
    (out, merged)
}

/// Step 5b: source triangles left unmerged by [`merge_pairs`] are paired with a later
/// leftover source triangle across a shared edge (same end points, opposite direction) into
/// a planar strictly convex quad, greedily in piece order, each triangle trying its longest
/// edge first. Encoders that reorder triangles
/// for the vertex cache (gltfpack, Draco's edgebreaker) leave a quad's two triangles apart;
/// without this the same surface would bake as twice the elements. Returns the pieces (a
/// quad where its first triangle was) and how many pairs were merged.
fn pair_by_edges(pieces: Vec<Piece>, tol: Tolerance) -> (Vec<Piece>, usize) {
    let leftover = |p: &Piece| p.source_triangle && p.vertices.len() == 3;
    // Directed edge (from, to) → the leftover triangle that has it.
    let mut edges: HashMap<(PointKey, PointKey), usize> = HashMap::new();
    for (k, piece) in pieces.iter().enumerate().filter(|(_, p)| leftover(p)) {
        for i in 0..3 {
            let (a, b) = (piece.vertices[i], piece.vertices[(i + 1) % 3]);
            edges.entry((point_key(a), point_key(b))).or_insert(k);
        }
    }
    if edges.is_empty() {
        return (pieces, 0);
    }
    let mut taken = vec![false; pieces.len()];
    let mut quads: HashMap<usize, Vec<DVec3>> = HashMap::new();
    for (k, piece) in pieces.iter().enumerate() {
        if !leftover(piece) || taken[k] {
            continue;
        }
        // Longest edge first: a quad's two triangles share its diagonal, their longest edge
        // (pairing across a short edge makes sheared quads of neighbouring cells).
        let v = &piece.vertices;
        let mut order = [0usize, 1, 2];
        order.sort_by(|&x, &y| {
            let length = |i: usize| v[i].distance_squared(v[(i + 1) % 3]);
            length(y).total_cmp(&length(x)).then(x.cmp(&y))
        });
        for i in order {
            let (a, b) = (piece.vertices[i], piece.vertices[(i + 1) % 3]);
            let Some(&j) = edges.get(&(point_key(b), point_key(a))) else {
                continue;
            };
            if j <= k || taken[j] {
                continue;
            }
            if let Some(quad) =
                merge_triangles(&piece.vertices, &pieces[j].vertices, tol.same_point)
            {
                taken[k] = true;
                taken[j] = true;
                quads.insert(k, quad);
                break;
            }
        }
    }
    let merged = quads.len();
    if merged == 0 {
        return (pieces, 0);
    }
    let mut out = Vec::with_capacity(pieces.len() - merged);
    for (k, piece) in pieces.into_iter().enumerate() {
        match quads.remove(&k) {
            Some(vertices) => out.push(Piece {
                face: piece.face,
                vertices,
                source_triangle: false,
            }),
            // Taken without a quad of its own: the second triangle of a pair.
            None if taken[k] => {}
            None => out.push(piece),
        }
    }
    (out, merged)
}

/// Two triangles that share an edge (in opposite directions: consistent winding), lie in
/// one plane and whose union is strictly convex make a quad; returns its vertices.
/// Shared vertices are compared by position within `eps`; the quad keeps the first
/// triangle's positions.
fn merge_triangles(a: &[DVec3], b: &[DVec3], eps: f64) -> Option<Vec<DVec3>> {
    let same = |u: DVec3, v: DVec3| u.distance(v) <= eps;
    for i in 0..3 {
        let (p, q) = (a[i], a[(i + 1) % 3]);
        for j in 0..3 {
            if same(b[j], q) && same(b[(j + 1) % 3], p) {
                let apex = b[(j + 2) % 3];
                let quad = vec![q, a[(i + 2) % 3], p, apex];
                return is_planar_convex_pair(a, b, &quad).then_some(quad);
            }
        }
    }
    None
}

/// Both triangles face the same way, the quad is planar and every corner turns left.
fn is_planar_convex_pair(a: &[DVec3], b: &[DVec3], quad: &[DVec3]) -> bool {
    let normal = newell(a).normalize_or_zero();
    newell(b).dot(normal) > 0.0 && is_planar(quad) && (0..4).all(|i| turn(quad, i, normal) > TURN)
}

/// Every vertex lies within `PLANAR` × the polygon's size of its mean (Newell) plane.
fn is_planar(v: &[DVec3]) -> bool {
    let normal = newell(v).normalize_or_zero();
    let centre = v.iter().copied().sum::<DVec3>() / v.len() as f64;
    let size = polygon_size(v);
    v.iter()
        .all(|p| (*p - centre).dot(normal).abs() <= PLANAR * size)
}

/// The diagonal of the polygon's bounding box.
fn polygon_size(v: &[DVec3]) -> f64 {
    let lo = v
        .iter()
        .copied()
        .fold(DVec3::splat(f64::INFINITY), DVec3::min);
    let hi = v
        .iter()
        .copied()
        .fold(DVec3::splat(f64::NEG_INFINITY), DVec3::max);
    (hi - lo).length()
}

/// The sine of the turning angle at corner `i` about `normal`: > 0 turns left (convex).
fn turn(v: &[DVec3], i: usize, normal: DVec3) -> f64 {
    let n = v.len();
    let e1 = v[i] - v[(i + n - 1) % n];
    let e2 = v[(i + 1) % n] - v[i];
    let lengths = e1.length() * e2.length();
    if lengths == 0.0 {
        return 0.0;
    }
    e1.cross(e2).dot(normal) / lengths
}

/// Newell's method: twice the vector area of a polygon (its normal times twice its area).
/// Coordinates are taken relative to the first vertex to limit cancellation.
pub(crate) fn newell(v: &[DVec3]) -> DVec3 {
    let Some(&first) = v.first() else {
        return DVec3::ZERO;
    };
    let n = v.len();
    (0..n)
        .map(|i| (v[i] - first).cross(v[(i + 1) % n] - first))
        .sum()
}

/// The polygon's area (exact for planar polygons).
fn area(v: &[DVec3]) -> f64 {
    newell(v).length() * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    fn one_face(vertices: Vec<DVec3>) -> Vec<Polygon> {
        let instance = Instance {
            label: "mesh 0, primitive 0".into(),
            place: String::new(),
            origin: Origin {
                node: 0,
                mesh: 0,
                primitive: 0,
                face: 0,
                side: Side::Front,
            },
            material: 0,
            double_sided: false,
            faces: vec![SourceFace { face: 0, vertices }],
        };
        let mut stats = ImportStats::default();
        bake(&[instance], &mut stats, &mut Vec::new()).unwrap()
    }

    #[test]
    fn newell_gives_twice_the_area() {
        let square = [d(0., 0., 0.), d(2., 0., 0.), d(2., 2., 0.), d(0., 2., 0.)];
        assert_eq!(newell(&square), d(0., 0., 8.));
    }

    #[test]
    fn remove_repeats_is_cyclic() {
        let v = [
            d(0., 0., 0.),
            d(0., 0., 0.),
            d(1., 0., 0.),
            d(0., 1., 0.),
            d(0., 0., 0.),
        ];
        assert_eq!(remove_repeats(&v, 0.0).len(), 3);
    }

    #[test]
    fn concave_quad_is_cut_at_its_reflex_corner() {
        // Dart: corner 2 at (1, 0.5) is reflex; the inner diagonal is 2-0.
        let polygons = one_face(vec![
            d(0., 0., 0.),
            d(2., 0., 0.),
            d(1., 0.5, 0.),
            d(1., 2., 0.),
        ]);
        assert_eq!(polygons.len(), 2);
        let total: f64 = polygons.iter().map(|p| area(&p.vertices)).sum();
        // Shoelace area of the dart: 1.25.
        assert!((total - 1.25).abs() < 1e-12);
        for p in &polygons {
            assert_eq!(p.vertices[0], d(1., 0.5, 0.));
            assert!((p.normal - d(0., 0., 1.)).length() < 1e-12);
        }
    }

    #[test]
    fn concave_hexagon_is_ear_clipped_inside() {
        // An L shape: six corners, one reflex.
        let l = vec![
            d(0., 0., 0.),
            d(2., 0., 0.),
            d(2., 1., 0.),
            d(1., 1., 0.),
            d(1., 2., 0.),
            d(0., 2., 0.),
        ];
        let polygons = one_face(l);
        let total: f64 = polygons.iter().map(|p| area(&p.vertices)).sum();
        assert!((total - 3.0).abs() < 1e-12, "area {total}");
        for p in &polygons {
            assert!((p.normal - d(0., 0., 1.)).length() < 1e-12);
            assert!((0..p.vertices.len()).all(|i| turn(&p.vertices, i, p.normal) > 0.0));
        }
    }
}
