//! The hierarchical operator on closed enclosures: the area-weighted row sum is exactly 1 (eq.
//! 15 with reciprocity, the furnace identity), which only holds if every tree covers its
//! polygon's elements exactly once (quad grids of odd and uneven sizes, triangle grids split
//! into four and into elements) and the links partition every polygon pair; each row tends to
//! 1 as the link tolerance shrinks; and the operator is reciprocal (`A_i (F x)_i` summed against y equals the same with x, y
//! swapped).

use bake_transport::{HierarchicalOptions, HierarchicalTransport};
use form_factor::{ContourOptions, Estimator};
use glam::DVec3;
use importer::{Origin, Polygon, Side};
use mesher::Subdivision;
use solver::Operator;
use visibility::Occluders;

fn polygon(mut vertices: Vec<DVec3>, inside: DVec3) -> Polygon {
    let mut n = (vertices[1] - vertices[0])
        .cross(vertices[2] - vertices[0])
        .normalize();
    if n.dot(inside - vertices[0]) < 0.0 {
        vertices.reverse();
        n = -n;
    }
    Polygon {
        vertices,
        normal: n,
        material: 0,
        origin: Origin {
            node: 0,
            mesh: 0,
            primitive: 0,
            face: 0,
            side: Side::Front,
        },
    }
}

/// A box 1 × 2 × 3 (so grids are uneven) seen from inside.
fn box_walls() -> Vec<Polygon> {
    let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let inside = c(0.5, 1.0, 1.5);
    let (x, y, z) = (1.0, 2.0, 3.0);
    vec![
        polygon(
            vec![c(0., 0., 0.), c(x, 0., 0.), c(x, y, 0.), c(0., y, 0.)],
            inside,
        ),
        polygon(
            vec![c(0., 0., z), c(x, 0., z), c(x, y, z), c(0., y, z)],
            inside,
        ),
        polygon(
            vec![c(0., 0., 0.), c(x, 0., 0.), c(x, 0., z), c(0., 0., z)],
            inside,
        ),
        polygon(
            vec![c(0., y, 0.), c(x, y, 0.), c(x, y, z), c(0., y, z)],
            inside,
        ),
        polygon(
            vec![c(0., 0., 0.), c(0., y, 0.), c(0., y, z), c(0., 0., z)],
            inside,
        ),
        polygon(
            vec![c(x, 0., 0.), c(x, y, 0.), c(x, y, z), c(x, 0., z)],
            inside,
        ),
    ]
}

/// A regular tetrahedron seen from inside: four triangles.
fn tetrahedron() -> Vec<Polygon> {
    let v = [
        DVec3::new(1., 1., 1.),
        DVec3::new(1., -1., -1.),
        DVec3::new(-1., 1., -1.),
        DVec3::new(-1., -1., 1.),
    ];
    [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]
        .iter()
        .map(|f| polygon(f.iter().map(|&k| v[k]).collect(), DVec3::ZERO))
        .collect()
}

fn build(
    polygons: &[Polygon],
    subdivision: Subdivision,
    tolerance: f64,
) -> (HierarchicalTransport, Vec<f64>) {
    build_on(
        polygons,
        mesher::mesh(polygons, subdivision).expect("mesh"),
        tolerance,
    )
}

/// Refines `mesh` twice: every third element, then every second element of those quarters
/// that lie in the first half of each polygon's range (levels 0, 1 and 2 side by side, with
/// hanging vertices).
fn refined(mesh: mesher::ElementMesh) -> mesher::ElementMesh {
    let first: Vec<bool> = (0..mesh.elements.len()).map(|i| i % 3 == 0).collect();
    let once = mesh.refine(&first).expect("refine").mesh;
    let second: Vec<bool> = (0..once.elements.len())
        .map(|i| {
            let p = &once.patches[once.elements[i].polygon as usize].elements;
            once.level(i) == 1 && i % 2 == 0 && (i as u32) < (p.start + p.end) / 2
        })
        .collect();
    let twice = once.refine(&second).expect("refine").mesh;
    assert!((0..twice.elements.len()).any(|i| twice.level(i) == 2));
    twice
}

/// Per element: emission 1 on the first polygon, 0 elsewhere.
fn first_polygon_emits(mesh: &mesher::ElementMesh) -> Vec<[f64; 3]> {
    mesh.elements
        .iter()
        .map(|el| if el.polygon == 0 { [1.0; 3] } else { [0.0; 3] })
        .collect()
}

fn build_on(
    polygons: &[Polygon],
    mesh: mesher::ElementMesh,
    tolerance: f64,
) -> (HierarchicalTransport, Vec<f64>) {
    build_with(polygons, mesh, tolerance, true)
}

fn build_with(
    polygons: &[Polygon],
    mesh: mesher::ElementMesh,
    tolerance: f64,
    shadow_masks: bool,
) -> (HierarchicalTransport, Vec<f64>) {
    let occluders = Occluders::new(polygons).expect("occluders");
    let n = mesh.elements.len();
    // The first polygon emits, everything reflects half.
    let e = first_polygon_emits(&mesh);
    let rho = vec![[0.5; 3]; n];
    let options = HierarchicalOptions {
        link_tolerance: bake_transport::LinkTolerance::OfMeanRadiosity(tolerance),
        estimator: Estimator::Contour,
        contour: ContourOptions::default(),
        shadow_masks,
        ..HierarchicalOptions::default()
    };
    let h = HierarchicalTransport::build(polygons, &mesh, &occluders, &rho, &e, &options, &|_| {})
        .expect("build");
    let areas = mesh.elements.iter().map(|el| el.area).collect();
    (h, areas)
}

/// Reciprocity, `A_i F_ij = A_j F_ji`: `Σ A_i (F x)_i y_i = Σ A_i (F y)_i x_i` for two
/// arbitrary vectors, to rounding.
fn check_reciprocity(h: &HierarchicalTransport, areas: &[f64]) {
    let n = h.n();
    let x: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64).collect();
    let y: Vec<f64> = (0..n).map(|i| ((i * 104729) % 17) as f64).collect();
    let (mut fx, mut fy) = (vec![0.0; n], vec![0.0; n]);
    h.apply(&x, &mut fx);
    h.apply(&y, &mut fy);
    let a: f64 = (0..n).map(|i| areas[i] * fx[i] * y[i]).sum();
    let b: f64 = (0..n).map(|i| areas[i] * fy[i] * x[i]).sum();
    assert!((a - b).abs() <= 1e-12 * a.abs(), "{a} vs {b}");
}

fn check_furnace_and_reciprocity(polygons: &[Polygon], subdivision: Subdivision) {
    check_operator(polygons, subdivision, false);
}

/// The furnace identity and reciprocity of the operator on the grids, or (`refine`) on a
/// mesh refined below them ([`refined`]).
fn check_operator(polygons: &[Polygon], subdivision: Subdivision, refine: bool) {
    let mut previous = f64::INFINITY;
    for tolerance in [1e-1, 1e-2, 1e-3] {
        let mesh = mesher::mesh(polygons, subdivision).expect("mesh");
        let mesh = if refine { refined(mesh) } else { mesh };
        let (h, areas) = build_on(polygons, mesh, tolerance);
        let n = h.n();
        let mut sums = vec![0.0; n];
        h.apply(&vec![1.0; n], &mut sums);
        // A leaf's row sum is 1 only up to the links' receiver error (a coarse link gives every
        // element of its receiver the receiver's mean), but the area-weighted mean is exactly 1
        // in a closed enclosure when the trees cover every element once and the links
        // partition every polygon pair (Σ_i A_i (F 1)_i = Σ_i A_i by reciprocity, eq. 14).
        let total: f64 = areas.iter().sum();
        let mean = (0..n).map(|i| areas[i] * sums[i]).sum::<f64>() / total;
        assert!(
            (mean - 1.0).abs() < 1e-9,
            "{subdivision:?} at {tolerance}: area-weighted row sum {mean}"
        );
        let worst = sums.iter().map(|s| (s - 1.0f64).abs()).fold(0.0, f64::max);
        // Links between whole polygons of a closed enclosure give row sums of exactly 1 (the
        // least-squares planes of the kernels towards all polygons, fitted at the same points,
        // sum to the plane of Σ_j F_xj = 1): refinement then departs from it, and the bound
        // below applies from the first refined tolerance on.
        assert!(
            worst < previous || worst < 1e-12 || previous < 1e-12,
            "{subdivision:?}: worst |row sum − 1| {worst} at {tolerance} ≥ {previous}"
        );
        previous = worst;
        check_reciprocity(&h, &areas);
        assert!(h.stats().links > 0);
    }
}

#[test]
fn quad_trees_of_uneven_grids_cover_every_element_once() {
    for size in [0.3, 0.45, 1.0] {
        check_furnace_and_reciprocity(&box_walls(), Subdivision::MaxSize(size));
    }
}

#[test]
fn triangle_trees_cover_every_element_once() {
    // 4 = 2·2 (split into four twice), 6 = 2·3 (four, then elements), 5 (elements at once).
    for n in [4, 5, 6] {
        check_furnace_and_reciprocity(&tetrahedron(), Subdivision::Count(n));
    }
}

#[test]
fn trees_of_refined_meshes_cover_every_element_once() {
    // Below the grids: quads and triangles split into quarters at two levels, beside
    // unsplit elements (the trees continue below grid elements into their quarters).
    for size in [0.45, 1.0] {
        check_operator(&box_walls(), Subdivision::MaxSize(size), true);
    }
    for n in [4, 5] {
        check_operator(&tetrahedron(), Subdivision::Count(n), true);
    }
}

#[test]
fn apply_bands_gives_the_bits_of_three_applies() {
    let (h, _) = build(&box_walls(), Subdivision::MaxSize(0.3), 1e-2);
    let n = h.n();
    let x: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, 1.0, (i % 5) as f64]).collect();
    let mut y = vec![[0.0; 3]; n];
    h.apply_bands(&x, &mut y);
    for c in 0..3 {
        let xc: Vec<f64> = x.iter().map(|v| v[c]).collect();
        let mut yc = vec![0.0; n];
        h.apply(&xc, &mut yc);
        assert!(yc
            .iter()
            .zip(&y)
            .all(|(a, b)| a.to_bits() == b[c].to_bits()));
    }
}

#[test]
fn too_many_links_is_a_clear_refusal() {
    let polygons = box_walls();
    let mesh = mesher::mesh(&polygons, Subdivision::MaxSize(0.3)).expect("mesh");
    let occluders = Occluders::new(&polygons).expect("occluders");
    let n = mesh.elements.len();
    let e = first_polygon_emits(&mesh);
    let options = HierarchicalOptions {
        link_tolerance: bake_transport::LinkTolerance::OfMeanRadiosity(1e-3),
        max_links: 10,
        ..HierarchicalOptions::default()
    };
    let result = HierarchicalTransport::build(
        &polygons,
        &mesh,
        &occluders,
        &vec![[0.5; 3]; n],
        &e,
        &options,
        &|_| {},
    );
    let message = match result {
        Err(e) => e.to_string(),
        Ok(_) => panic!("10 links cannot hold a refined box"),
    };
    assert!(message.contains("more than 10 links"), "{message}");
    assert!(message.contains("--link-tolerance"), "{message}");
}

/// The six walls of a unit cube at `at`, seen from inside.
fn sealed_box(at: DVec3) -> Vec<Polygon> {
    let inside = at + DVec3::splat(0.5);
    reference::box_walls(at, DVec3::ONE)
        .iter()
        .map(|f| polygon(f.to_vec(), inside))
        .collect()
}

#[test]
fn sealed_rooms_exchange_no_light_and_their_cluster_pairs_are_dropped() {
    // A 4 × 3 grid of sealed boxes 0.5 apart: no light can pass between two of them (every
    // ray between their insides crosses a wall), so the first pass drops their cluster pairs
    // instead of screening every polygon pair, and what is left still partitions each box's
    // own pairs (the furnace identity per box).
    let mut polygons = Vec::new();
    for k in 0..12 {
        let at = DVec3::new(f64::from(k % 4) * 1.5, 0.0, f64::from(k / 4) * 1.5);
        polygons.extend(sealed_box(at));
    }
    let (h, areas) = build(&polygons, Subdivision::MaxSize(0.25), 1e-2);
    let stats = h.stats();
    let p = polygons.len() as u64;
    assert!(stats.clusters_dropped > 0, "{stats:?}");
    // Each box's 15 polygon pairs are linked; of the 2 376 pairs between boxes, the descent
    // leaves only some of the neighbours' (a box's whole light bounds what the rays can miss
    // only at a distance).
    let all = p * (p - 1) / 2;
    assert!(stats.polygon_pairs >= 12 * 15, "{stats:?}");
    assert!(
        stats.polygon_pairs < all / 2,
        "{} of {all} polygon pairs linked: {stats:?}",
        stats.polygon_pairs
    );
    let mesh = mesher::mesh(&polygons, Subdivision::MaxSize(0.25)).expect("mesh");
    let n = h.n();
    // Light from box 0 only: nothing may arrive anywhere else.
    let x: Vec<f64> = mesh
        .elements
        .iter()
        .map(|el| if el.polygon < 6 { 1.0 } else { 0.0 })
        .collect();
    let mut y = vec![0.0; n];
    h.apply(&x, &mut y);
    for (k, el) in mesh.elements.iter().enumerate() {
        if el.polygon >= 6 {
            assert_eq!(y[k], 0.0, "element {k} of polygon {}", el.polygon);
        }
    }
    // Per box, the area-weighted row sum of F 1 is exactly 1 (closed, reciprocal links).
    let mut sums = vec![0.0; n];
    h.apply(&vec![1.0; n], &mut sums);
    for b in 0..12 {
        let (mut weighted, mut total) = (0.0, 0.0);
        for (k, el) in mesh.elements.iter().enumerate() {
            if el.polygon as usize / 6 == b {
                weighted += areas[k] * sums[k];
                total += areas[k];
            }
        }
        assert!(
            (weighted / total - 1.0).abs() < 1e-9,
            "box {b}: area-weighted row sum {}",
            weighted / total
        );
    }
}

/// Saves `h` with `key` and loads it back: the same links, accuracy and bits of `F x`. Returns
/// the saved bytes.
fn check_save_and_load(
    h: &HierarchicalTransport,
    polygons: &[Polygon],
    mesh: &mesher::ElementMesh,
    key: u64,
) -> Vec<u8> {
    let mut bytes = Vec::new();
    h.save(key, &mut bytes).expect("save to memory");
    let loaded =
        HierarchicalTransport::load(polygons, mesh, key, &mut bytes.as_slice()).expect("load");
    assert_eq!(loaded.stats().links, h.stats().links);
    let n = h.n();
    let x: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64).collect();
    let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
    h.apply(&x, &mut a);
    loaded.apply(&x, &mut b);
    assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
    assert_eq!(loaded.accuracy(), h.accuracy());
    bytes
}

#[test]
fn saved_links_load_to_the_same_operator_and_damage_is_refused() {
    let polygons = box_walls();
    let subdivision = Subdivision::MaxSize(0.3);
    let (h, _) = build(&polygons, subdivision, 1e-2);
    let mesh = mesher::mesh(&polygons, subdivision).expect("mesh");
    let bytes = check_save_and_load(&h, &polygons, &mesh, 0xfeed);

    let load =
        |bytes: &[u8], key: u64, mesh: &mesher::ElementMesh| match HierarchicalTransport::load(
            &polygons,
            mesh,
            key,
            &mut &bytes[..],
        ) {
            Ok(_) => String::from("loaded"),
            Err(e) => e.to_string(),
        };
    assert!(load(&bytes, 0xbeef, &mesh).contains("other geometry or link options"));
    assert!(load(b"GLTF", 0xfeed, &mesh).contains("not a links file"));
    // Truncated anywhere after the header: a read error, never a panic.
    for cut in [20, 60, bytes.len() / 2, bytes.len() - 1] {
        let message = load(&bytes[..cut], 0xfeed, &mesh);
        assert_ne!(message, "loaded", "cut at {cut}");
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(load(&longer, 0xfeed, &mesh).contains("after the last"));
    // A NaN coefficient (the first one follows the header, offsets and sources).
    let nodes = h.stats().nodes as usize;
    let entries = 2 * h.stats().links as usize;
    let first = 8 * 8 + 8 * (nodes + 1) + 4 * entries;
    let mut nan = bytes.clone();
    nan[first..first + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    assert!(load(&nan, 0xfeed, &mesh).contains("coefficient NaN"));
    // Another mesh of the same polygons has other trees.
    let finer = mesher::mesh(&polygons, Subdivision::MaxSize(0.2)).expect("mesh");
    assert!(load(&bytes, 0xfeed, &finer).contains("elements"));
}

/// Progress nobody listens to.
struct Quiet;

impl bake_transport::Progress for Quiet {
    fn start(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

/// The box of [`box_walls`] meshed, with its occluders, the first polygon emitting and every
/// element reflecting half: what [`BoxScene::problem`] lends to `bake_transport::build`.
struct BoxScene {
    polygons: Vec<Polygon>,
    mesh: mesher::ElementMesh,
    occluders: Occluders,
    e: Vec<[f64; 3]>,
    rho: Vec<[f64; 3]>,
}

impl BoxScene {
    fn new(subdivision: Subdivision) -> BoxScene {
        let polygons = box_walls();
        let mesh = mesher::mesh(&polygons, subdivision).expect("mesh");
        let occluders = Occluders::new(&polygons).expect("occluders");
        let e = first_polygon_emits(&mesh);
        let rho = vec![[0.5; 3]; mesh.elements.len()];
        BoxScene {
            polygons,
            mesh,
            occluders,
            e,
            rho,
        }
    }

    fn problem(&self) -> bake_transport::Problem<'_> {
        bake_transport::Problem {
            polygons: &self.polygons,
            mesh: &self.mesh,
            occluders: &self.occluders,
            rho: &self.rho,
            source: &self.e,
        }
    }
}

/// `transport::build` gives the same operator as building it directly, and its view passes
/// on what the operator says of itself: the hierarchy's rows are not bounded by 1 (each
/// element gets its ancestors' averages), a dense matrix's are; only the dense one has
/// entries for LU, only the hierarchy links to save.
#[test]
fn build_gives_each_kind_and_its_view_says_what_it_can_do() {
    let scene = BoxScene::new(Subdivision::Count(3));
    let (polygons, mesh, n) = (&scene.polygons, &scene.mesh, scene.mesh.elements.len());
    let (direct, _) = build_on(polygons, mesh.clone(), 0.01);
    let problem = scene.problem();
    let hierarchical = bake_transport::Options::Hierarchical(HierarchicalOptions {
        link_tolerance: bake_transport::LinkTolerance::OfMeanRadiosity(0.01),
        estimator: Estimator::Contour,
        contour: ContourOptions::default(),
        ..HierarchicalOptions::default()
    });
    let mut stages = Vec::new();
    let built = bake_transport::build(&problem, &hierarchical, &Quiet, &mut |s| stages.push(s))
        .expect("links");
    assert_eq!(stages, ["links"]);
    let view = built.operator.view().expect("a view");
    assert!(!view.rows_bounded() && !direct.rows_bounded());
    assert!(view.dense().is_none());
    let ones = vec![1.0; n];
    let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
    view.apply(&ones, &mut a);
    direct.apply(&ones, &mut b);
    assert_eq!(a, b, "the same links either way");
    assert!(built.operator.into_links().is_some());

    let dense = bake_transport::Options::Dense(bake_transport::DenseOptions {
        estimator: Estimator::Contour,
        contour: ContourOptions::default(),
        samples: 16,
        row_sum_margin: 0.05,
    });
    let mut stages = Vec::new();
    let built =
        bake_transport::build(&problem, &dense, &Quiet, &mut |s| stages.push(s)).expect("dense");
    assert_eq!(stages, ["occludable_pairs", "form_factors"]);
    let view = built.operator.view().expect("a view");
    assert!(view.rows_bounded());
    let f = view.dense().expect("entries");
    assert_eq!(f.n(), n);
    // A closed box: every row of the exact matrix sums to 1 (eq. 15).
    for i in 0..n {
        let sum: f64 = f.row(i).iter().sum();
        assert!((sum - 1.0).abs() < 1e-6, "row {i}: {sum}");
    }
    assert!(built.operator.into_links().is_none());
}

/// A 4 × 3 × 4 room seen from inside, its ceiling first (the emitter of [`build`]), with a
/// 1 × 1 × 1 block standing on the floor at (1.5…2.5, 1.5…2.5): top and sides facing out,
/// open below (as the desks of the office floors), so the floor under it sees nothing.
fn room_with_block() -> Vec<Polygon> {
    let c = DVec3::new;
    let mut faces: Vec<Polygon> = reference::box_walls(DVec3::ZERO, c(4.0, 3.0, 4.0))
        .iter()
        .map(|f| polygon(f.to_vec(), c(2.0, 1.5, 2.0)))
        .collect();
    // The ceiling (the face at y = 3) first.
    let ceiling = faces
        .iter()
        .position(|p| p.vertices.iter().all(|v| v.y == 3.0))
        .expect("a ceiling");
    faces.swap(0, ceiling);
    let (lo, hi) = (c(1.5, 0.0, 1.5), c(2.5, 1.0, 2.5));
    let centre = (lo + hi) / 2.0;
    for f in reference::box_walls(lo, hi - lo) {
        let mid = f.iter().copied().sum::<DVec3>() / 4.0;
        if mid.y == 0.0 {
            continue;
        }
        // Facing out: towards a point beyond the face.
        faces.push(polygon(f.to_vec(), mid + (mid - centre)));
    }
    faces
}

/// Whether a point of the floor of [`room_with_block`] is under the block.
fn under_block(c: DVec3) -> bool {
    c.y == 0.0 && (1.5..=2.5).contains(&c.x) && (1.5..=2.5).contains(&c.z)
}

#[test]
fn shadow_masks_keep_hidden_elements_dark_and_the_operator_reciprocal() {
    // Coarse links between the floor and the ceiling or walls are occludable (the block can
    // come between): spread by area, their light would reach the floor under the block. The
    // masks spread it by each element's own rays, and weight what the floor sends the same
    // way, so the hidden elements receive exactly nothing and A_i F_ij = A_j F_ji still holds.
    let polygons = room_with_block();
    let subdivision = Subdivision::MaxSize(0.5);
    let mesh = mesher::mesh(&polygons, subdivision).expect("mesh");
    let (h, areas) = build(&polygons, subdivision, 1e-2);
    let stats = h.stats();
    assert!(stats.masked_nodes > 0 && stats.mask_rays > 0, "{stats:?}");
    let n = h.n();
    let e: Vec<f64> = first_polygon_emits(&mesh).iter().map(|v| v[0]).collect();
    let mut first = vec![0.0; n];
    h.apply(&e, &mut first);
    let mut all = vec![0.0; n];
    h.apply(&vec![1.0; n], &mut all);
    let (mut hidden, mut lit_floor) = (0, 0);
    for (k, el) in mesh.elements.iter().enumerate() {
        let centre = el.centroid;
        let under =
            centre.y == 0.0 && (1.5..=2.5).contains(&centre.x) && (1.5..=2.5).contains(&centre.z);
        if under {
            hidden += 1;
            assert_eq!(
                first[k], 0.0,
                "hidden element {k} receives from the ceiling"
            );
            assert_eq!(all[k], 0.0, "hidden element {k} receives");
        } else if centre.y == 0.0 && first[k] > 0.0 {
            lit_floor += 1;
        }
    }
    assert_eq!(hidden, 4);
    assert_eq!(lit_floor, 60);
    // Without masks the same links light them (what the masks are for).
    let (plain, _) = build_with(&polygons, mesh.clone(), 1e-2, false);
    assert_eq!(plain.stats().masked_nodes, 0);
    let mut leaked = vec![0.0; n];
    plain.apply(&e, &mut leaked);
    let under: Vec<usize> = (0..n)
        .filter(|&k| under_block(mesh.elements[k].centroid))
        .collect();
    assert!(under.iter().all(|&k| leaked[k] > 0.0), "{under:?}");
    check_reciprocity(&h, &areas);
}

#[test]
fn saved_links_keep_their_shadow_masks() {
    // The masks travel with the links (format 2): the loaded operator gives the same bits,
    // and a damaged mask scale is refused.
    let polygons = room_with_block();
    let subdivision = Subdivision::MaxSize(0.5);
    let (h, _) = build(&polygons, subdivision, 1e-2);
    assert!(h.stats().masked_nodes > 0);
    let mesh = mesher::mesh(&polygons, subdivision).expect("mesh");
    let bytes = check_save_and_load(&h, &polygons, &mesh, 7);
    // The last 8 bytes are the last mask scale.
    let mut damaged = bytes.clone();
    let end = damaged.len();
    damaged[end - 8..].copy_from_slice(&(-1.0f64).to_le_bytes());
    let message = match HierarchicalTransport::load(&polygons, &mesh, 7, &mut damaged.as_slice()) {
        Ok(_) => String::from("loaded"),
        Err(e) => e.to_string(),
    };
    assert!(message.contains("mask scale -1"), "{message}");
}

/// The links' error estimate (`link_error`) bounds what coarse links miss: on an unoccluded
/// closed box (no visibility involved), for a smooth radiosity x, each element's irradiance
/// `(F x)_i` through coarse links differs from the exact contour-integral matrix's by at most
/// its estimate for ≥ 95% of element-bands (the estimate combines links in quadrature: an
/// estimate, not a strict bound), and it is not vacuous (the median of difference / estimate
/// is ≥ 0.1; measured 96.1% and 0.25).
/// Element–element links are exact: at a tolerance fine enough to link elements only, the
/// estimate is 0.
#[test]
fn link_error_bounds_the_coarse_links_irradiance_error() {
    let scene = BoxScene::new(Subdivision::MaxSize(0.2));
    let (polygons, mesh, n) = (&scene.polygons, &scene.mesh, scene.mesh.elements.len());
    let problem = scene.problem();
    let dense = bake_transport::Options::Dense(bake_transport::DenseOptions {
        estimator: Estimator::Contour,
        contour: ContourOptions::default(),
        samples: 16,
        row_sum_margin: 0.05,
    });
    let built = bake_transport::build(&problem, &dense, &Quiet, &mut |_| {}).expect("dense");
    let view = built.operator.view().expect("a view");
    assert!(view.link_error(&[[1.0; 3]]).is_none(), "dense: no links");
    // A smooth, non-constant radiosity (three bands differently).
    let x: Vec<[f64; 3]> = mesh
        .elements
        .iter()
        .map(|el| {
            let c = el.centroid;
            [1.0 + 0.5 * c.x, 1.0 + 0.3 * c.y, 2.0 - 0.2 * c.z]
        })
        .collect();
    let mut exact = vec![[0.0; 3]; n];
    view.apply_bands(&x, &mut exact);
    let (mut bounded, mut ratios) = (0, Vec::new());
    for tolerance in [3e-2, 1e-2] {
        let (h, _) = build(polygons, Subdivision::MaxSize(0.2), tolerance);
        let mut coarse = vec![[0.0; 3]; n];
        h.apply_bands(&x, &mut coarse);
        let estimate = h.link_error(&x).models;
        assert_eq!(estimate.len(), n);
        for i in 0..n {
            for c in 0..3 {
                let truth = (coarse[i][c] - exact[i][c]).abs();
                bounded += usize::from(truth <= estimate[i][c] + 1e-12);
                ratios.push(truth / estimate[i][c].max(1e-300));
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len() / 2];
    let share = bounded as f64 / ratios.len() as f64;
    println!("bounded {share:.3}, median truth/estimate {median:.3}");
    assert!(share >= 0.95, "bounded {share}");
    assert!(median >= 0.1, "median truth/estimate {median}");
    let (fine, _) = build(polygons, Subdivision::Count(2), 1e-9);
    assert!(fine
        .link_error(&x[..fine.n()])
        .models
        .iter()
        .flatten()
        .all(|&v| v == 0.0));
}
