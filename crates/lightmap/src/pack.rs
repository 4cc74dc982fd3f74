//! Packs regions into one atlas with `etagere`'s shelf allocator, in units of 2×2 texel
//! blocks (so every region starts on an even texel), trying several atlas widths and keeping
//! the smallest atlas.

use crate::mask::Mask;
use etagere::{size2, AllocatorOptions, AtlasAllocator};

/// Where each region goes and the atlas size, in texels.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Packing {
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// Top-left corner of each region, in the order given.
    pub(crate) positions: Vec<(u32, u32)>,
}

/// etagere's coordinates are 16-bit.
const MAX_BLOCKS: u32 = u16::MAX as u32;
/// etagere allocation ids are 16-bit.
pub(crate) const MAX_REGIONS: usize = 65_000;

/// Packs `sizes` (even, in texels) into the smallest atlas found whose sides are at most
/// `max` texels; `None` when none fits.
pub(crate) fn pack(sizes: &[(u32, u32)], max: u32) -> Option<Packing> {
    if sizes.len() > MAX_REGIONS {
        return None;
    }
    // Tallest first: shelves fill evenly (etagere's notes: ~85% occupancy sorted by height).
    let widths = (0..=24).map(|step| 0.9 + 0.025 * f64::from(step));
    smallest(sizes, (max / 2).min(MAX_BLOCKS), widths, pack_width)
}

/// One packing pass: blocks, their order, the strip width and the most height (blocks) →
/// the height used and each position (blocks).
type Pass = fn(&[(u32, u32)], &[usize], u32, u32) -> Option<(u32, Vec<(u32, u32)>)>;

/// Runs `pass` over `sizes` (even, in texels) in 2×2 blocks, tallest first, at strip
/// widths `factors` × the side of the blocks' total area (at most `max_blocks`), keeping
/// the smallest (then squarest) atlas.
fn smallest(
    sizes: &[(u32, u32)],
    max_blocks: u32,
    factors: impl Iterator<Item = f64>,
    pass: Pass,
) -> Option<Packing> {
    if sizes.is_empty() {
        return None;
    }
    let blocks: Vec<(u32, u32)> = sizes.iter().map(|&(w, h)| (w / 2, h / 2)).collect();
    let widest = blocks.iter().map(|b| b.0).max()?;
    let tallest = blocks.iter().map(|b| b.1).max()?;
    if widest > max_blocks || tallest > max_blocks {
        return None;
    }
    let area: u64 = blocks
        .iter()
        .map(|&(w, h)| u64::from(w) * u64::from(h))
        .sum();
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    order.sort_by_key(|&k| {
        (
            std::cmp::Reverse(blocks[k].1),
            std::cmp::Reverse(blocks[k].0),
            k,
        )
    });
    let side = (area as f64).sqrt();
    let mut best: Option<(u64, u32, Packing)> = None;
    let mut tried = Vec::new();
    for factor in factors {
        let width = ((side * factor).ceil() as u32).clamp(widest, max_blocks);
        if tried.contains(&width) {
            continue;
        }
        tried.push(width);
        let Some((used_height, positions)) = pass(&blocks, &order, width, max_blocks) else {
            continue;
        };
        let cost = u64::from(width) * u64::from(used_height);
        let squareness = width.max(used_height);
        if best
            .as_ref()
            .is_none_or(|(c, s, _)| (cost, squareness) < (*c, *s))
        {
            let packing = Packing {
                width: 2 * width,
                height: 2 * used_height,
                positions: positions.iter().map(|&(x, y)| (2 * x, 2 * y)).collect(),
            };
            best = Some((cost, squareness, packing));
        }
    }
    best.map(|(_, _, packing)| packing)
}

/// Packs into a `width`-block wide strip at most `max_height` blocks tall; the height used
/// and each region's position, in blocks.
fn pack_width(
    blocks: &[(u32, u32)],
    order: &[usize],
    width: u32,
    max_height: u32,
) -> Option<(u32, Vec<(u32, u32)>)> {
    let options = AllocatorOptions {
        alignment: size2(1, 1),
        vertical_shelves: false,
        num_columns: 1,
    };
    let mut atlas = AtlasAllocator::with_options(size2(width as i32, max_height as i32), &options);
    let mut positions = vec![(0, 0); blocks.len()];
    let mut used = 0;
    for &k in order {
        let (w, h) = blocks[k];
        let allocation = atlas.allocate(size2(w as i32, h as i32))?;
        let r = allocation.rectangle;
        positions[k] = (r.min.x as u32, r.min.y as u32);
        used = used.max(r.min.y as u32 + h);
    }
    Some((used, positions))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_do_not_overlap_and_fit() {
        let sizes: Vec<(u32, u32)> = (0..200)
            .map(|k| (2 * (3 + k * 7 % 40), 2 * (2 + k * 13 % 30)))
            .collect();
        let p = pack(&sizes, 4096).expect("fits");
        for (a, &(xa, ya)) in p.positions.iter().enumerate() {
            let (wa, ha) = sizes[a];
            assert!(xa + wa <= p.width && ya + ha <= p.height);
            assert_eq!((xa % 2, ya % 2), (0, 0));
            for (b, &(xb, yb)) in p.positions.iter().enumerate().skip(a + 1) {
                let (wb, hb) = sizes[b];
                let apart = xa + wa <= xb || xb + wb <= xa || ya + ha <= yb || yb + hb <= ya;
                assert!(apart, "{a} and {b} overlap");
            }
        }
        assert!(pack(&sizes, 64).is_none());
    }
}

/// Packs `masks` (each a region's column spans, in 2×2 blocks) with a profile skyline:
/// largest first, each where it rests lowest on the columns below it — a column's span
/// rests on the highest block packed in that column so far, so a ragged chart's short
/// columns take the space beside another's tall ones — then leftmost; trying several atlas
/// widths and keeping the smallest atlas. Positions and sizes in texels; `None` when no
/// width keeps both sides within `max` texels. O(masks × atlas width × mask width) a width.
pub(crate) fn pack_masks(masks: &[&Mask], max: u32) -> Option<Packing> {
    let max_blocks = (max / 2).min(MAX_BLOCKS);
    let widest = masks.iter().map(|m| m.width).max()?;
    let tallest = masks.iter().map(|m| m.height).max()?;
    if widest > max_blocks || tallest > max_blocks {
        return None;
    }
    let area: u64 = masks.iter().map(|m| m.blocks()).sum();
    let mut order: Vec<usize> = (0..masks.len()).collect();
    order.sort_by_key(|&k| {
        let m = masks[k];
        (std::cmp::Reverse(m.height), std::cmp::Reverse(m.width), k)
    });
    let side = (area as f64).sqrt();
    let mut widths: Vec<u32> = (0..=12)
        .map(|step| {
            ((side * (1.0 + 0.05 * f64::from(step))).ceil() as u32).clamp(widest, max_blocks)
        })
        .collect();
    widths.dedup();
    // The widths in parallel; the smallest (then squarest, then first) atlas kept.
    use rayon::prelude::*;
    let passes: Vec<Option<Packing>> = widths
        .par_iter()
        .map(|&width| {
            profile_width(masks, &order, width, max_blocks).map(|(used, p)| Packing {
                width: 2 * width,
                height: 2 * used,
                positions: p.iter().map(|&(x, y)| (2 * x, 2 * y)).collect(),
            })
        })
        .collect();
    passes.into_iter().flatten().min_by_key(|p| {
        (
            u64::from(p.width) * u64::from(p.height),
            p.width.max(p.height),
        )
    })
}

/// One profile-skyline pass at `width` blocks: the height used and positions (blocks).
fn profile_width(
    masks: &[&Mask],
    order: &[usize],
    width: u32,
    max_height: u32,
) -> Option<(u32, Vec<(u32, u32)>)> {
    // Per atlas column: one past its highest used block.
    let mut sky = vec![0u32; width as usize];
    let mut positions = vec![(0, 0); masks.len()];
    let mut used = 0;
    for &k in order {
        let m = masks[k];
        // (top, waste, x, y): lowest top, then least space left under it, then leftmost.
        let mut choice: Option<(u32, u64, u32, u32)> = None;
        for x in 0..=(width - m.width) {
            let mut y = 0u32;
            for (c, &(a, b)) in m.columns.iter().enumerate() {
                if b > a {
                    y = y.max(sky[x as usize + c].saturating_sub(a));
                }
            }
            let top = y + m.height;
            if top > max_height {
                continue;
            }
            if choice.is_some_and(|(t, ..)| top > t) {
                continue;
            }
            let waste: u64 = m
                .columns
                .iter()
                .enumerate()
                .filter(|(_, &(a, b))| b > a)
                .map(|(c, &(a, _))| u64::from(y + a - sky[x as usize + c].min(y + a)))
                .sum();
            if choice.is_none_or(|(t, w, ..)| (top, waste) < (t, w)) {
                choice = Some((top, waste, x, y));
            }
        }
        let (_, _, x, y) = choice?;
        for (c, &(a, b)) in m.columns.iter().enumerate() {
            if b > a {
                let s = &mut sky[x as usize + c];
                *s = (*s).max(y + b);
                used = used.max(y + b);
            }
        }
        positions[k] = (x, y);
    }
    Some((used, positions))
}

#[cfg(test)]
mod mask_tests {
    use super::*;
    use glam::DVec2;

    /// Right triangles of many sizes (each a region with its padding) and one large one:
    /// masks never share a block, stay inside the atlas, and a triangle's empty half takes
    /// other regions, so the blocks used exceed what the regions' rectangles would allow.
    #[test]
    fn masks_never_share_a_block_and_fill_beside_ragged_regions() {
        let p = f64::from(crate::PADDING);
        let triangle = |w: f64, h: f64| {
            let width = 2 * ((w + 2.0 * p) / 2.0).ceil() as u32;
            let height = 2 * ((h + 2.0 * p) / 2.0).ceil() as u32;
            let uv = vec![DVec2::new(p, p), DVec2::new(p + w, p), DVec2::new(p, p + h)];
            crate::mask::mask(width, height, &[(0, uv)])
        };
        let mut masks = vec![triangle(300.0, 300.0)];
        masks.extend(
            (0..400).map(|k| triangle(4.0 + f64::from(k * 7 % 40), 3.0 + f64::from(k * 13 % 30))),
        );
        let refs: Vec<&Mask> = masks.iter().collect();
        let packing = pack_masks(&refs, 4096).expect("fits");
        let (w, h) = (packing.width as usize / 2, packing.height as usize / 2);
        let mut used = vec![false; w * h];
        for (m, &(x, y)) in masks.iter().zip(&packing.positions) {
            assert_eq!((x % 2, y % 2), (0, 0));
            for (c, &(a, b)) in m.columns.iter().enumerate() {
                for r in a..b {
                    let (bx, by) = (x as usize / 2 + c, y as usize / 2 + r as usize);
                    assert!(bx < w && by < h, "outside the atlas");
                    assert!(!used[by * w + bx], "two masks share block ({bx}, {by})");
                    used[by * w + bx] = true;
                }
            }
        }
        let blocks = used.iter().filter(|&&u| u).count() as f64;
        let rectangles: f64 = masks
            .iter()
            .map(|m| f64::from(m.width) * f64::from(m.height))
            .sum();
        // The triangles' masks take about half their rectangles; packed, they fill the
        // atlas more than the rectangles alone could (their areas sum past the atlas).
        assert!(blocks / (w * h) as f64 > 0.7, "{}", blocks / (w * h) as f64);
        println!("{} blocks of {}, rectangles {rectangles}", blocks, w * h);
        assert!(
            ((w * h) as f64) < 0.9 * rectangles,
            "{} {rectangles}",
            w * h
        );
        assert!(pack_masks(&refs, 256).is_none());
    }
}
