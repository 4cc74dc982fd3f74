//! Byte encodings glTF files use: base64 for `data:` URIs and the GLB container.

/// Standard base64 with padding (RFC 4648 §4), for `data:` URIs.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// `bytes` as a `data:application/octet-stream;base64,…` URI (a glTF buffer).
pub fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64(bytes))
}

/// The GLB chunk type of the JSON chunk.
pub const GLB_JSON: [u8; 4] = *b"JSON";
/// The GLB chunk type of the binary buffer chunk.
pub const GLB_BIN: [u8; 4] = *b"BIN\0";

/// A GLB container (glTF 2.0, "GLB File Format"): the 12-byte header (magic, version 2,
/// total length), then each `(type, data)` chunk with its length, padded to 4 bytes (the
/// JSON chunk with spaces, every other chunk with zeros).
pub fn glb(chunks: &[([u8; 4], &[u8])]) -> Vec<u8> {
    let padded: Vec<([u8; 4], Vec<u8>)> = chunks
        .iter()
        .map(|&(kind, data)| {
            let mut data = data.to_vec();
            let with = if kind == GLB_JSON { b' ' } else { 0 };
            data.resize(data.len().next_multiple_of(4), with);
            (kind, data)
        })
        .collect();
    let total = 12 + padded.iter().map(|(_, d)| 8 + d.len()).sum::<usize>();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    for (kind, data) in &padded {
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
    }
    out
}

/// The `(type, data)` chunks of the GLB `bytes`, in order; `None` when `bytes` do not start
/// with the GLB magic or a chunk runs past their end. The header's version and total length
/// are not checked.
pub fn glb_chunks(bytes: &[u8]) -> Option<Vec<([u8; 4], &[u8])>> {
    if !bytes.starts_with(b"glTF") {
        return None;
    }
    let word = |at: usize| -> Option<usize> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as usize)
    };
    let mut chunks = Vec::new();
    let mut at = 12;
    while at < bytes.len() {
        let length = word(at)?;
        let kind: [u8; 4] = bytes.get(at + 4..at + 8)?.try_into().ok()?;
        chunks.push((kind, bytes.get(at + 8..at + 8 + length)?));
        at += 8 + length;
    }
    Some(chunks)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        let vectors = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in vectors {
            assert_eq!(base64(plain.as_bytes()), encoded, "{plain:?}");
        }
    }

    #[test]
    fn glb_pads_chunks_and_reads_back() {
        let bytes = glb(&[(GLB_JSON, b"{}"), (GLB_BIN, &[1, 2, 3, 4, 5])]);
        assert_eq!(bytes.len(), 12 + 8 + 4 + 8 + 8);
        assert_eq!(&bytes[8..12], &(bytes.len() as u32).to_le_bytes());
        let chunks = glb_chunks(&bytes).expect("a GLB");
        assert_eq!(chunks.len(), 2);
        assert_eq!(chunks[0], (GLB_JSON, &b"{}  "[..]));
        assert_eq!(chunks[1], (GLB_BIN, &[1, 2, 3, 4, 5, 0, 0, 0][..]));
        assert!(glb_chunks(&bytes[..bytes.len() - 1]).is_none());
        assert!(glb_chunks(b"{}").is_none());
    }
}
