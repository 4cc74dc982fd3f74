//! A built hierarchy's operator on disk, for re-bakes whose geometry and link options did not
//! change (`--save-links` / `--load-links`): only emission or colours changed, so the links
//! and their form factors and visible fractions still hold, and a re-bake is the solve alone.
//!
//! The trees are not stored: they are rebuilt from the mesh (deterministically) and their node
//! count is checked. The caller's `key` (a hash of geometry and options) must match.
//!
//! Layout, little-endian: `b"BAKELNK4"`, key u64, elements u64, nodes u64, entries u64,
//! accuracy f64, links u64, blocked links u64; `offsets` (nodes + 1) × u64, `sources`
//! entries × u32, `coefficients` entries × f64, `gradients` entries × 6 × f32, `residuals`
//! entries × 3 × f32 (over the receiver, over the source, the visibility's relative deviation), `masked` entries × u8 (0 or 1); then the shadow masks (`masks.rs`): their count M u64, nodes
//! M × u32, offsets (M + 1) × u64, centroids M × 3 × f64, and per mask entry its element u32
//! and scale f64. Every value is checked on reading (monotone offsets, nodes and elements in
//! range, finite non-negative coefficients and scales, finite gradients and centroids, a mask
//! for every masked entry's node, residuals finite and non-negative): a damaged file is an error, never a panic or a NaN.
//! Versions 1 (before the masks), 2 (before the residuals) and 3 (before the visibility
//! deviation) are refused as not of this version.

use super::{build_trees, Entries, HierarchicalStats, HierarchicalTransport, Masks, NONE};
use glam::DVec3;
use mesher::ElementMesh;
use scene::Polygon;
use std::io::{self, Read, Write};

const MAGIC: &[u8; 8] = b"BAKELNK4";

/// Why a links file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum LinksFileError {
    #[error("not a links file of this version of bake (no BAKELNK4 header)")]
    NotALinksFile,
    #[error(
        "the links were built for other geometry or link options (key {found:016x}, this bake \
         needs {expected:016x}); bake without --load-links to build them again"
    )]
    Mismatch { expected: u64, found: u64 },
    #[error("the links file is damaged: {0}")]
    Damaged(String),
    #[error("cannot read the links file: {0}")]
    Io(#[from] io::Error),
}

impl HierarchicalTransport {
    /// Writes the operator with `key` (see the module docs).
    pub fn save(&self, key: u64, w: &mut dyn Write) -> io::Result<()> {
        let e = &self.entries;
        w.write_all(MAGIC)?;
        for v in [
            key,
            self.n as u64,
            self.nodes.len() as u64,
            e.sources.len() as u64,
        ] {
            w.write_all(&v.to_le_bytes())?;
        }
        w.write_all(&self.accuracy.to_le_bytes())?;
        w.write_all(&self.stats.links.to_le_bytes())?;
        w.write_all(&self.stats.blocked_links.to_le_bytes())?;
        for v in &e.offsets {
            w.write_all(&v.to_le_bytes())?;
        }
        for v in &e.sources {
            w.write_all(&v.to_le_bytes())?;
        }
        for v in &e.coefficients {
            w.write_all(&v.to_le_bytes())?;
        }
        for g in &e.gradients {
            for v in g.iter().flatten() {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        for v in e.residuals.iter().flatten() {
            w.write_all(&v.to_le_bytes())?;
        }
        let flags: Vec<u8> = e.masked.iter().map(|&m| u8::from(m)).collect();
        w.write_all(&flags)?;
        let m = &self.masks;
        w.write_all(&(m.node.len() as u64).to_le_bytes())?;
        for v in &m.node {
            w.write_all(&v.to_le_bytes())?;
        }
        for v in &m.offsets {
            w.write_all(&v.to_le_bytes())?;
        }
        for c in &m.centroid {
            for v in c.to_array() {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        for v in &m.leaves {
            w.write_all(&v.to_le_bytes())?;
        }
        for v in &m.scale {
            w.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    }

    /// Reads an operator saved by [`HierarchicalTransport::save`] for `mesh` (made from
    /// `polygons`), refusing it unless its key is `key` and it fits the rebuilt trees.
    pub fn load(
        polygons: &[Polygon],
        mesh: &ElementMesh,
        key: u64,
        r: &mut dyn Read,
    ) -> Result<HierarchicalTransport, LinksFileError> {
        let mut magic = [0u8; 8];
        r.read_exact(&mut magic)
            .map_err(|_| LinksFileError::NotALinksFile)?;
        if &magic != MAGIC {
            return Err(LinksFileError::NotALinksFile);
        }
        let found = read_u64(r)?;
        if found != key {
            return Err(LinksFileError::Mismatch {
                expected: key,
                found,
            });
        }
        let damaged = |what: String| LinksFileError::Damaged(what);
        let (elements, node_count, entry_count) = (read_u64(r)?, read_u64(r)?, read_u64(r)?);
        let accuracy = f64::from_bits(read_u64(r)?);
        let (links, blocked_links) = (read_u64(r)?, read_u64(r)?);
        let (nodes, children, _) =
            build_trees(polygons, mesh).map_err(|e| damaged(e.to_string()))?;
        let n = mesh.elements.len();
        if elements != n as u64 || node_count != nodes.len() as u64 {
            return Err(damaged(format!(
                "{elements} elements and {node_count} nodes, the mesh has {n} and {}",
                nodes.len()
            )));
        }
        if !(accuracy.is_finite() && accuracy >= 0.0) {
            return Err(damaged(format!("accuracy {accuracy}")));
        }
        // Every light-carrying link is two entries, one per direction.
        if links.checked_mul(2) != Some(entry_count) {
            return Err(damaged(format!("{entry_count} entries for {links} links")));
        }
        let entries =
            usize::try_from(entry_count).map_err(|_| damaged(format!("{entry_count} entries")))?;
        // Vectors grow as entries are read: a count the file does not back with bytes ends
        // in a read error, not in an allocation of what it claims.
        let reserve = entries.min(1 << 20);
        let mut offsets = Vec::with_capacity(nodes.len() + 1);
        let mut previous = 0;
        for k in 0..=nodes.len() {
            let v = read_u64(r)?;
            if v < previous || v > entry_count || (k == 0 && v != 0) {
                return Err(damaged(format!("offset {v} of node {k}")));
            }
            previous = v;
            offsets.push(v);
        }
        if previous != entry_count {
            return Err(damaged(format!(
                "offsets end at {previous}, not {entry_count}"
            )));
        }
        let mut sources = Vec::with_capacity(reserve);
        let mut buffer = [0u8; 24];
        for _ in 0..entries {
            r.read_exact(&mut buffer[..4])?;
            let s = u32::from_le_bytes([buffer[0], buffer[1], buffer[2], buffer[3]]);
            if s as usize >= nodes.len() {
                return Err(damaged(format!("source node {s}")));
            }
            sources.push(s);
        }
        let mut coefficients = Vec::with_capacity(reserve);
        for _ in 0..entries {
            let c = f64::from_bits(read_u64(r)?);
            if !(c.is_finite() && c >= 0.0) {
                return Err(damaged(format!("coefficient {c}")));
            }
            coefficients.push(c);
        }
        let mut gradients = Vec::with_capacity(reserve);
        for _ in 0..entries {
            r.read_exact(&mut buffer)?;
            let mut g = [[0.0f32; 3]; 2];
            for (k, v) in g.iter_mut().flatten().enumerate() {
                let b = &buffer[4 * k..4 * k + 4];
                *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                if !v.is_finite() {
                    return Err(damaged(format!("gradient {v}")));
                }
            }
            gradients.push(g);
        }
        let mut residuals = Vec::with_capacity(reserve);
        for _ in 0..entries {
            r.read_exact(&mut buffer[..12])?;
            let mut v = [0.0f32; 3];
            for (k, x) in v.iter_mut().enumerate() {
                let b = &buffer[4 * k..4 * k + 4];
                *x = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                if !(x.is_finite() && *x >= 0.0) {
                    return Err(damaged(format!("residual {x}")));
                }
            }
            residuals.push(v);
        }
        let mut masked = Vec::with_capacity(reserve);
        for _ in 0..entries {
            r.read_exact(&mut buffer[..1])?;
            match buffer[0] {
                0 => masked.push(false),
                1 => masked.push(true),
                v => return Err(damaged(format!("mask flag {v}"))),
            }
        }
        let masks = read_masks(r, n, nodes.len())?;
        // Every masked entry's interior ends have masks (else their light would be dropped).
        for (receiver, pair) in offsets.windows(2).enumerate() {
            for k in pair[0] as usize..pair[1] as usize {
                let source = sources[k] as usize;
                if masked[k]
                    && [receiver, source]
                        .iter()
                        .any(|&u| u >= n && masks.of_node[u] == NONE)
                {
                    return Err(damaged(format!(
                        "masked entry {k} of a node without a mask"
                    )));
                }
            }
        }
        let mut rest = [0u8; 1];
        if r.read(&mut rest)? != 0 {
            return Err(damaged("bytes after the last mask".into()));
        }
        let stats = HierarchicalStats {
            nodes: nodes.len() as u64,
            links,
            blocked_links,
            masked_nodes: masks.node.len() as u64,
            ..HierarchicalStats::default()
        };
        Ok(HierarchicalTransport {
            n,
            nodes,
            children,
            entries: Entries {
                offsets,
                sources,
                coefficients,
                gradients,
                masked,
                residuals,
            },
            masks,
            accuracy,
            stats,
        })
    }
}

/// The shadow masks of a links file over `n` elements and `total` nodes (module docs).
fn read_masks(r: &mut dyn Read, n: usize, total: usize) -> Result<Masks, LinksFileError> {
    let damaged = |what: String| LinksFileError::Damaged(what);
    let count = read_u64(r)?;
    if count > (total - n) as u64 {
        return Err(damaged(format!("{count} masks over {} nodes", total - n)));
    }
    let count = count as usize;
    let mut masks = Masks::none(total);
    let mut buffer = [0u8; 4];
    for _ in 0..count {
        r.read_exact(&mut buffer)?;
        let node = u32::from_le_bytes(buffer);
        let previous = masks.node.last().copied();
        if (node as usize) < n || node as usize >= total || previous.is_some_and(|p| p >= node) {
            return Err(damaged(format!("mask node {node}")));
        }
        masks.of_node[node as usize] = masks.node.len() as u32;
        masks.node.push(node);
    }
    masks.offsets.clear();
    let mut previous = 0;
    for k in 0..=count {
        let v = read_u64(r)?;
        if v < previous || (k == 0 && v != 0) || v > (n as u64).saturating_mul(64) {
            return Err(damaged(format!("mask offset {v}")));
        }
        previous = v;
        masks.offsets.push(v);
    }
    for _ in 0..count {
        let c = [read_u64(r)?, read_u64(r)?, read_u64(r)?].map(f64::from_bits);
        if !c.iter().all(|v| v.is_finite()) {
            return Err(damaged(format!("mask centroid {c:?}")));
        }
        masks.centroid.push(DVec3::from_array(c));
    }
    for _ in 0..previous {
        r.read_exact(&mut buffer)?;
        let leaf = u32::from_le_bytes(buffer);
        if leaf as usize >= n {
            return Err(damaged(format!("mask element {leaf}")));
        }
        masks.leaves.push(leaf);
    }
    for _ in 0..previous {
        let s = f64::from_bits(read_u64(r)?);
        if !(s.is_finite() && s >= 0.0) {
            return Err(damaged(format!("mask scale {s}")));
        }
        masks.scale.push(s);
    }
    Ok(masks)
}

fn read_u64(r: &mut dyn Read) -> io::Result<u64> {
    let mut b = [0u8; 8];
    r.read_exact(&mut b)?;
    Ok(u64::from_le_bytes(b))
}
