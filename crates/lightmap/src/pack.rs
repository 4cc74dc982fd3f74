//! Packs regions into one atlas with `etagere`'s shelf allocator, in units of 2×2 texel
//! blocks (so every region starts on an even texel), trying several atlas widths and keeping
//! the smallest atlas.

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

/// Packs `sizes` (even, in texels) with a bottom-left skyline, in 2×2 texel blocks: tallest
/// first, each rectangle where its top ends lowest (then leftmost), trying several atlas
/// widths and keeping the smallest atlas. Unlike a shelf allocator, small rectangles stack
/// beside a tall one instead of leaving its shelf empty: the packer for grouped charts,
/// whose sizes range from a whole terrain to a table leg. O(n × skyline segments).
pub(crate) fn pack_skyline(sizes: &[(u32, u32)], max: u32) -> Option<Packing> {
    let widths = (0..=16).map(|step| 1.0 + 0.05 * f64::from(step));
    smallest(sizes, max / 2, widths, skyline_width)
}

/// One skyline pass at `width` blocks: the height used and the positions (blocks).
fn skyline_width(
    blocks: &[(u32, u32)],
    order: &[usize],
    width: u32,
    max_height: u32,
) -> Option<(u32, Vec<(u32, u32)>)> {
    // Segments (x, top) in x order; segment k runs to the next one's x (the last to width).
    let mut sky: Vec<(u32, u32)> = vec![(0, 0)];
    let mut positions = vec![(0, 0); blocks.len()];
    let mut used = 0;
    for &k in order {
        let (w, h) = blocks[k];
        let mut choice: Option<(u32, u32, usize)> = None; // (top, x, first segment)
        for i in 0..sky.len() {
            let x = sky[i].0;
            if x + w > width {
                break;
            }
            let mut y = 0;
            for seg in &sky[i..] {
                if seg.0 >= x + w {
                    break;
                }
                y = y.max(seg.1);
            }
            let top = y + h;
            if top <= max_height && choice.is_none_or(|(t, cx, _)| (top, x) < (t, cx)) {
                choice = Some((top, x, i));
            }
        }
        let (top, x, i) = choice?;
        positions[k] = (x, top - h);
        used = used.max(top);
        // The height at x + w before the change, then replace the covered segments.
        let end = x + w;
        let mut j = i;
        let mut after = sky[i].1;
        while j < sky.len() && sky[j].0 < end {
            after = sky[j].1;
            j += 1;
        }
        let mut replacement = vec![(x, top)];
        if end < width && sky.get(j).is_none_or(|s| s.0 > end) {
            replacement.push((end, after));
        }
        sky.splice(i..j, replacement);
        // Merge neighbours of equal height.
        sky.dedup_by(|b, a| a.1 == b.1);
    }
    Some((used, positions))
}

#[cfg(test)]
mod skyline_tests {
    use super::*;

    #[test]
    fn skyline_regions_do_not_overlap_and_stack_beside_a_tall_one() {
        let mut sizes: Vec<(u32, u32)> = vec![(400, 400)];
        sizes.extend((0..300).map(|k| (2 * (3 + k * 7 % 20), 2 * (2 + k * 13 % 15))));
        let p = pack_skyline(&sizes, 4096).expect("fits");
        for (a, &(xa, ya)) in p.positions.iter().enumerate() {
            let (wa, ha) = sizes[a];
            assert!(xa + wa <= p.width && ya + ha <= p.height);
            for (b, &(xb, yb)) in p.positions.iter().enumerate().skip(a + 1) {
                let (wb, hb) = sizes[b];
                let apart = xa + wa <= xb || xb + wb <= xa || ya + ha <= yb || yb + hb <= ya;
                assert!(apart, "{a} and {b} overlap");
            }
        }
        let area: u64 = sizes
            .iter()
            .map(|&(w, h)| u64::from(w) * u64::from(h))
            .sum();
        let used = f64::from(p.width) * f64::from(p.height);
        assert!(area as f64 / used > 0.8, "{}", area as f64 / used);
        assert!(pack_skyline(&sizes, 256).is_none());
    }
}
