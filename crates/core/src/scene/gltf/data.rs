//! The bytes behind a glTF document: the JSON (or GLB) parsed and validated by the `gltf`
//! crate, then every buffer read (the GLB binary chunk, a `data:` URI, or a file beside the
//! model) and checked against the lengths the JSON gives, so that everything read later
//! lies inside the data it names. Images are read the same way, on demand.

use std::path::{Path, PathBuf};

use super::invalid;
use crate::scene::SceneError;

/// A parsed glTF file and its buffers (index = the JSON's `buffers` index).
pub(super) struct Source {
    pub doc: ::gltf::Document,
    pub buffers: Vec<Vec<u8>>,
    /// The folder relative URIs are resolved in.
    pub dir: PathBuf,
    /// The file as displayed in messages.
    pub file: String,
}

/// Most validation errors listed in one message.
const LISTED_ERRORS: usize = 4;

/// Reads and parses `path` and all its buffers.
pub(super) fn read(path: &Path) -> Result<Source, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file = path.display().to_string();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    parse(&bytes, file, dir)
}

/// Parses glTF or GLB `bytes` (display name `file`, relative URIs resolved in `dir`).
pub(super) fn parse(bytes: &[u8], file: String, dir: PathBuf) -> Result<Source, SceneError> {
    let parsed = std::panic::catch_unwind(|| {
        let gltf = ::gltf::Gltf::from_slice_without_validation(bytes)?;
        let attributes = attribute_indices(gltf.document.as_json());
        Ok((attributes, gltf))
    });
    let (attributes, gltf) = parsed
        .map_err(|_| invalid(&file, "", "the glTF parser failed on this file"))?
        .map_err(|e| parse_error(&file, e))?;
    attributes.map_err(|(at, m)| invalid(&file, &at, m))?;
    let mut blob = gltf.blob;
    let doc = std::panic::catch_unwind(|| ::gltf::Document::from_json(gltf.document.into_json()))
        .map_err(|_| invalid(&file, "", "the glTF validation failed on this file"))?
        .map_err(|e| parse_error(&file, e))?;
    let mut buffers = Vec::new();
    for b in doc.buffers() {
        let at = format!("buffers[{}]", b.index());
        let data = match b.source() {
            ::gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                invalid(
                    &file,
                    &at,
                    "refers to the GLB binary chunk, which is missing",
                )
            })?,
            ::gltf::buffer::Source::Uri(uri) => {
                read_uri(uri, &dir).map_err(|m| invalid(&file, &format!("{at}.uri"), m))?
            }
        };
        if data.len() < b.length() {
            return Err(invalid(
                &file,
                &at,
                format!(
                    "has {} bytes, fewer than its byteLength {} (truncated?)",
                    data.len(),
                    b.length()
                ),
            ));
        }
        buffers.push(data);
    }
    for v in doc.views() {
        let len = buffers.get(v.buffer().index()).map_or(0, Vec::len);
        let end = v.offset().checked_add(v.length());
        if end.is_none_or(|e| e > len) {
            return Err(invalid(
                &file,
                &format!("bufferViews[{}]", v.index()),
                format!(
                    "bytes {}..{} lie outside buffers[{}] ({len} bytes)",
                    v.offset(),
                    v.offset().saturating_add(v.length()),
                    v.buffer().index()
                ),
            ));
        }
    }
    Ok(Source {
        doc,
        buffers,
        dir,
        file,
    })
}

/// Checks that every primitive attribute names an accessor that exists, which the `gltf`
/// crate's validation assumes of POSITION (it indexes the accessors with it).
fn attribute_indices(root: &::gltf::json::Root) -> Result<(), (String, String)> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= root.accessors.len() {
                    let name = match semantic {
                        ::gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        ::gltf::json::validation::Checked::Invalid => "?".into(),
                    };
                    return Err((
                        format!("meshes[{m}].primitives[{p}].attributes.{name}"),
                        format!(
                            "accessors[{}] does not exist ({} accessors)",
                            index.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The `gltf` crate's error as a message naming the JSON paths it found wrong.
fn parse_error(file: &str, e: ::gltf::Error) -> SceneError {
    match e {
        ::gltf::Error::Validation(errors) => {
            let mut listed: Vec<String> = errors
                .iter()
                .take(LISTED_ERRORS)
                .map(|(path, err)| format!("{path}: {err}"))
                .collect();
            if errors.len() > LISTED_ERRORS {
                listed.push(format!("and {} more", errors.len() - LISTED_ERRORS));
            }
            invalid(file, "", format!("invalid glTF: {}", listed.join("; ")))
        }
        other => invalid(file, "", format!("not a readable glTF 2.0 file: {other}")),
    }
}

impl Source {
    /// The encoded bytes of image `image` (from a buffer view, a `data:` URI or a file).
    pub fn image_bytes(&self, image: &::gltf::Image) -> Result<Vec<u8>, String> {
        match image.source() {
            ::gltf::image::Source::View { view, .. } => {
                let data = &self.buffers[view.buffer().index()];
                Ok(data[view.offset()..view.offset() + view.length()].to_vec())
            }
            ::gltf::image::Source::Uri { uri, .. } => read_uri(uri, &self.dir),
        }
    }
}

/// The bytes a URI names: a `data:` URI decoded, else a file relative to `dir`.
fn read_uri(uri: &str, dir: &Path) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (head, payload) = rest
            .split_once(',')
            .ok_or("a data: URI without a ',' before its data")?;
        return if head.ends_with(";base64") {
            base64(payload).ok_or_else(|| "a data: URI whose base64 is malformed".into())
        } else {
            Ok(percent_decode(payload).into_bytes())
        };
    }
    if uri.contains("://") {
        return Err(format!(
            "'{uri}' is not a local file (only relative paths and data: URIs are read)"
        ));
    }
    let p = dir.join(percent_decode(uri));
    std::fs::read(&p).map_err(|e| format!("cannot read {}: {e}", p.display()))
}

/// `%XX` escapes decoded (as glTF URIs are written); invalid escapes are kept.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b
            .get(i + 1..i + 3)
            .and_then(|h| u8::from_str_radix(std::str::from_utf8(h).ok()?, 16).ok());
        match (b[i], hex) {
            (b'%', Some(x)) => {
                out.push(x);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Standard base64 (RFC 4648, `=` padding optional); `None` on any other character.
pub(super) fn base64(s: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let s = s.trim_end_matches('=').as_bytes();
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    for chunk in s.chunks(4) {
        if chunk.len() == 1 {
            return None;
        }
        let mut acc = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            acc |= value(c)? << (18 - 6 * k);
        }
        let bytes = acc.to_be_bytes();
        out.extend_from_slice(&bytes[1..chunk.len()]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_and_percent_escapes_decode() {
        assert_eq!(base64("TWFu").as_deref(), Some(&b"Man"[..]));
        assert_eq!(base64("TWE=").as_deref(), Some(&b"Ma"[..]));
        assert_eq!(base64("TQ==").as_deref(), Some(&b"M"[..]));
        assert_eq!(base64("").as_deref(), Some(&b""[..]));
        assert_eq!(base64("T"), None);
        assert_eq!(base64("TW!u"), None);
        assert_eq!(percent_decode("my%20box%2Fa.bin%zz"), "my box/a.bin%zz");
    }
}
