//! Totals of what a small file can make the importer allocate (zero-filled accessors,
//! decoded images), checked against the memory available before allocating: each item has
//! its own limit (`MAX_COUNT`, `MAX_TEXELS`), but a few kilobytes can name many items.

use crate::ImportError;
use gltf::json::Root;

/// Bytes of memory available now (`MemAvailable` of `/proc/meminfo`); `None` where that
/// cannot be told (no check is made then).
pub(crate) fn available() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    meminfo.lines().find_map(|line| {
        let kib = line
            .strip_prefix("MemAvailable:")?
            .trim()
            .strip_suffix("kB")?;
        kib.trim().parse::<u64>().ok()?.checked_mul(1024)
    })
}

/// Refuses `needed` bytes for `what` when more than `available`.
pub(crate) fn check(what: &str, needed: u64, available: Option<u64>) -> Result<(), ImportError> {
    match available {
        Some(free) if needed > free => Err(ImportError::ExceedsMemory(format!(
            "{what} need {} MiB, more than the {} MiB of memory available",
            needed.div_ceil(1 << 20),
            free >> 20
        ))),
        _ => Ok(()),
    }
}

/// Bytes the importer holds for one value of an accessor as it reads it (f64 components).
const BYTES_PER_COMPONENT: u64 = 8;

/// The accessors without a buffer view (zero-filled, glTF 2.0 "Accessors") that the
/// primitives read: each primitive reads its own copy, so a 3 KB file can ask for
/// gigabytes. Refused before any is read when their total exceeds `available`.
pub(crate) fn check_zero_filled(root: &Root, available: Option<u64>) -> Result<(), ImportError> {
    let mut total: u64 = 0;
    let mut accessors = 0usize;
    for mesh in &root.meshes {
        for primitive in &mesh.primitives {
            let used = primitive
                .attributes
                .values()
                .chain(primitive.indices.as_ref());
            for index in used {
                let Some(accessor) = root.accessors.get(index.value()) else {
                    continue;
                };
                if accessor.buffer_view.is_some() {
                    continue;
                }
                let components = match accessor.type_ {
                    gltf::json::validation::Checked::Valid(t) => t.multiplicity() as u64,
                    gltf::json::validation::Checked::Invalid => 16,
                };
                let bytes = accessor
                    .count
                    .0
                    .saturating_mul(components)
                    .saturating_mul(BYTES_PER_COMPONENT);
                total = total.saturating_add(bytes);
                accessors += 1;
            }
        }
    }
    check(
        &format!("{accessors} zero-filled accessor reads (accessors without a bufferView)"),
        total,
        available,
    )
}

/// Bytes decoding a `width` × `height` image holds at its peak: the decoder's buffer (up
/// to 16-bit RGBA, 8 bytes), its RGBA8 copy (4) and the linear texels and alpha (16).
pub(crate) fn decoded_image_bytes(width: u32, height: u32) -> u64 {
    u64::from(width) * u64::from(height) * (8 + 4 + 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_total_past_the_available_memory_is_refused() {
        assert!(check("x", 10, Some(10)).is_ok());
        assert!(check("x", 11, None).is_ok());
        let error = check("4 images", 3 << 30, Some(2 << 30)).expect_err("too much");
        assert!(matches!(error, ImportError::ExceedsMemory(_)));
        assert!(error.is_too_large());
        assert!(
            error.to_string().contains("4 images need 3072 MiB"),
            "{error}"
        );
        if std::path::Path::new("/proc/meminfo").exists() {
            assert!(available().is_some_and(|b| b > 0));
        }
    }
}
