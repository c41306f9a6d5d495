//! The OBJ pre-scan: every statement Nusselt relies on checked line by line before `tobj`
//! parses the file (so errors name `file:line`), and what the loader needs ahead of the
//! parse (face lines, which faces have texture coordinates, the material libraries and
//! the materials in use).
//!
//! A large export is hundreds of thousands of lines (the Crytek atrium: 748 k lines,
//! 26 MB) and the scan is on the path to the first image, so it runs in parallel over
//! blocks of lines. A face's indices are checked against the vertices defined *before*
//! it, so a first pass counts each block's `v`, `vt` and `vn` statements and each block
//! then starts from the counts before it. The blocks' results are joined in file order and
//! the first error in the file is the one reported, as a scan line by line would.

use std::collections::{HashMap, HashSet};

use rayon::prelude::*;

use super::SceneError;

/// Blocks of about this many bytes are scanned in parallel.
const BLOCK_BYTES: usize = 1 << 20;

/// What the OBJ pre-scan learned.
pub(super) struct ObjScan {
    pub face_lines: Vec<usize>,
    /// Per face, whether every vertex names a texture coordinate.
    pub face_uv: Vec<bool>,
    pub mtllibs: Vec<(String, usize)>,
    /// The material names `usemtl` asks for ([`material_key`]s).
    pub usemtl: HashSet<String>,
    pub warnings: Vec<String>,
}

pub(super) fn parse_err(file: &str, line: usize, message: impl Into<String>) -> SceneError {
    SceneError::Parse {
        file: file.to_string(),
        line,
        message: message.into(),
    }
}

/// A material name as a key: tobj keeps the text after `newmtl`, the scan its words.
pub(super) fn material_key(name: &str) -> String {
    name.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Checks that `words` are `min..=max` finite numbers, as statement `what` needs.
pub(super) fn check_numbers(
    file: &str,
    line: usize,
    what: &str,
    words: &[&str],
    min: usize,
    max: usize,
) -> Result<(), SceneError> {
    if words.len() < min || words.len() > max {
        let want = if min == max {
            format!("{min}")
        } else {
            format!("{min} to {max}")
        };
        return Err(parse_err(
            file,
            line,
            format!("'{what}' needs {want} numbers, found {}", words.len()),
        ));
    }
    for w in words {
        let x: f64 = w
            .parse()
            .map_err(|_| parse_err(file, line, format!("'{what}': '{w}' is not a number")))?;
        if !x.is_finite() {
            return Err(parse_err(
                file,
                line,
                format!("'{what}': '{w}' is not a finite number"),
            ));
        }
    }
    Ok(())
}

/// One block of whole lines and the number of its first line.
struct Block<'a> {
    text: &'a str,
    first_line: usize,
}

/// `text` cut at line ends into blocks of about [`BLOCK_BYTES`].
fn blocks(text: &str) -> Vec<Block<'_>> {
    let mut cuts = vec![0];
    let bytes = text.as_bytes();
    let mut at = BLOCK_BYTES;
    while at < bytes.len() {
        match bytes[at..].iter().position(|&b| b == b'\n') {
            Some(k) => {
                cuts.push(at + k + 1);
                at += k + 1 + BLOCK_BYTES;
            }
            None => break,
        }
    }
    cuts.push(bytes.len());
    cuts.dedup();
    let texts: Vec<&str> = cuts.windows(2).map(|w| &text[w[0]..w[1]]).collect();
    let newlines: Vec<usize> = texts
        .par_iter()
        .map(|t| t.bytes().filter(|&b| b == b'\n').count())
        .collect();
    let mut first_line = 1;
    texts
        .into_iter()
        .zip(newlines)
        .map(|(text, n)| {
            let block = Block { text, first_line };
            first_line += n;
            block
        })
        .collect()
}

/// The words of an OBJ or MTL line, before any `#` (a comment).
pub(super) fn words(raw: &str) -> std::str::SplitWhitespace<'_> {
    raw.split('#').next().unwrap_or("").split_whitespace()
}

/// The statements of `text`, numbered from `first_line`: the words before any `#`, into
/// a buffer reused from line to line.
fn for_each_statement<'a>(
    text: &'a str,
    first_line: usize,
    mut f: impl FnMut(usize, &[&'a str]) -> Result<(), SceneError>,
) -> Result<(), SceneError> {
    let mut words: Vec<&str> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        words.clear();
        words.extend(self::words(raw));
        if !words.is_empty() {
            f(first_line + i, &words)?;
        }
    }
    Ok(())
}

/// `v`, `vt` and `vn` statements in `text`.
fn count_vertices(text: &str) -> [i64; 3] {
    let mut n = [0i64; 3];
    for raw in text.lines() {
        match words(raw).next() {
            Some("v") => n[0] += 1,
            Some("vt") => n[1] += 1,
            Some("vn") => n[2] += 1,
            _ => {}
        }
    }
    n
}

/// What one block of lines gave.
#[derive(Default)]
struct BlockScan {
    face_lines: Vec<usize>,
    face_uv: Vec<bool>,
    mtllibs: Vec<(String, usize)>,
    usemtl: HashSet<String>,
    unknown: HashMap<String, usize>,
}

/// Checks one face vertex `a` (`v`, `v/vt`, `v//vn`, `v/vt/vn`) against the counts of
/// vertices, texture coordinates and normals defined so far; whether it names a `vt`.
fn face_vertex(file: &str, line: usize, a: &str, counts: [i64; 3]) -> Result<bool, SceneError> {
    if a.matches('/').count() > 2 {
        return Err(parse_err(file, line, format!("bad face vertex '{a}'")));
    }
    let mut parts = a.split('/');
    let mut has_uv = false;
    for (k, count) in counts.into_iter().enumerate() {
        let Some(p) = parts.next() else { break };
        if p.is_empty() {
            if k == 0 {
                return Err(parse_err(file, line, format!("bad face vertex '{a}'")));
            }
            continue;
        }
        let what = ["vertex", "texture coordinate", "normal"][k];
        let i: i64 = p
            .parse()
            .map_err(|_| parse_err(file, line, format!("bad {what} index '{p}' in '{a}'")))?;
        let resolved = if i < 0 { count + i + 1 } else { i };
        if i == 0 || resolved < 1 || resolved > count {
            return Err(parse_err(
                file,
                line,
                format!("{what} index {i} is out of range (1..={count} defined so far)"),
            ));
        }
        has_uv |= k == 1;
    }
    Ok(has_uv)
}

/// Scans one block, `counts` being the vertices, texture coordinates and normals defined
/// before it.
fn scan_block(file: &str, block: &Block, mut counts: [i64; 3]) -> Result<BlockScan, SceneError> {
    let mut scan = BlockScan::default();
    for_each_statement(block.text, block.first_line, |line, words| {
        let args = &words[1..];
        match words[0] {
            "v" => {
                check_numbers(file, line, "v", args, 3, 4)?;
                counts[0] += 1;
            }
            "vt" => {
                check_numbers(file, line, "vt", args, 1, 3)?;
                counts[1] += 1;
            }
            "vn" => {
                check_numbers(file, line, "vn", args, 3, 3)?;
                counts[2] += 1;
            }
            "f" => {
                if args.len() < 3 {
                    return Err(parse_err(
                        file,
                        line,
                        format!("a face needs at least 3 vertices, found {}", args.len()),
                    ));
                }
                let mut all_uv = true;
                for a in args {
                    all_uv &= face_vertex(file, line, a, counts)?;
                }
                scan.face_lines.push(line);
                scan.face_uv.push(all_uv);
            }
            "mtllib" => {
                if args.is_empty() {
                    return Err(parse_err(file, line, "'mtllib' needs a file name"));
                }
                scan.mtllibs.push((args.join(" "), line));
            }
            "usemtl" => {
                if args.is_empty() {
                    return Err(parse_err(file, line, "'usemtl' needs a material name"));
                }
                scan.usemtl.insert(material_key(&args.join(" ")));
            }
            "o" | "g" | "s" | "l" | "p" | "vp" | "cstype" | "deg" | "curv" | "surf" | "parm"
            | "end" | "mg" | "lod" | "usemap" | "maplib" | "bevel" | "c_interp" | "d_interp"
            | "shadow_obj" | "trace_obj" => {}
            other => *scan.unknown.entry(other.to_string()).or_default() += 1,
        }
        Ok(())
    })?;
    Ok(scan)
}

/// Checks `text` (the OBJ file `file`) statement by statement; the first error in the file
/// is returned.
pub(super) fn scan_obj(file: &str, text: &str) -> Result<ObjScan, SceneError> {
    let blocks = blocks(text);
    let counts: Vec<[i64; 3]> = blocks.par_iter().map(|b| count_vertices(b.text)).collect();
    let mut before = [0i64; 3];
    let starts: Vec<[i64; 3]> = counts
        .iter()
        .map(|c| {
            let start = before;
            for k in 0..3 {
                before[k] += c[k];
            }
            start
        })
        .collect();
    let scans: Vec<Result<BlockScan, SceneError>> = blocks
        .par_iter()
        .zip(starts)
        .map(|(b, start)| scan_block(file, b, start))
        .collect();
    let mut scan = ObjScan {
        face_lines: Vec::new(),
        face_uv: Vec::new(),
        mtllibs: Vec::new(),
        usemtl: HashSet::new(),
        warnings: Vec::new(),
    };
    let mut unknown: HashMap<String, usize> = HashMap::new();
    for block in scans {
        let block = block?;
        scan.face_lines.extend(block.face_lines);
        scan.face_uv.extend(block.face_uv);
        scan.mtllibs.extend(block.mtllibs);
        scan.usemtl.extend(block.usemtl);
        for (k, n) in block.unknown {
            *unknown.entry(k).or_default() += n;
        }
    }
    let mut unknown: Vec<_> = unknown.into_iter().collect();
    unknown.sort();
    for (k, n) in unknown {
        scan.warnings.push(format!(
            "{file}: ignored {n} line(s) with unknown statement '{k}'"
        ));
    }
    Ok(scan)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An OBJ of `n` triangles, each after its own three vertices, long enough to span
    /// several blocks.
    fn triangles(n: usize) -> String {
        let mut s = String::from("mtllib a.mtl\nusemtl white\n");
        for i in 0..n {
            let z = i as f64;
            s += &format!("v 0 0 {z}\nv 1 0 {z}\nv 0 1 {z}\nvt 0 0\nf -3/-1 -2/-1 -1/-1\n");
        }
        s
    }

    #[test]
    fn the_blocks_cover_every_line_once_with_its_number() {
        let text = triangles(60_000);
        let blocks = blocks(&text);
        assert!(blocks.len() > 2, "{} blocks", blocks.len());
        let joined: String = blocks.iter().map(|b| b.text).collect();
        assert_eq!(joined, text);
        let mut offset = 0;
        for b in &blocks {
            assert_eq!(b.first_line, text[..offset].matches('\n').count() + 1);
            assert!(b.text.ends_with('\n'), "a block ends at a line end");
            offset += b.text.len();
        }
    }

    #[test]
    fn a_large_file_scans_as_its_lines_say() {
        let n = 60_000;
        let scan = scan_obj("big.obj", &triangles(n)).unwrap();
        assert_eq!(scan.face_lines.len(), n);
        assert!(scan.face_uv.iter().all(|&uv| uv));
        // Face k is on line 2 + 5k + 5 (two header lines, then five lines a triangle).
        for (k, &line) in scan.face_lines.iter().enumerate().step_by(7919) {
            assert_eq!(line, 7 + 5 * k);
        }
        assert_eq!(scan.mtllibs, vec![("a.mtl".to_string(), 1)]);
        assert!(scan.usemtl.contains("white"));
    }

    #[test]
    fn an_index_past_the_vertices_so_far_is_refused_in_any_block() {
        let n = 60_000;
        let mut text = triangles(n);
        // A face near the end naming a vertex that is defined only after it.
        let bad_line = text.matches('\n').count() + 1;
        text += &format!("f 1 2 {}\nv 0 0 0\n", 3 * n + 1);
        let err = scan_obj("big.obj", &text).err().unwrap().to_string();
        assert!(err.contains(&format!("big.obj:{bad_line}")), "{err}");
        assert!(err.contains("out of range"), "{err}");
        // Of two errors the first in the file is reported.
        let mut text = triangles(n);
        text.insert_str(0, "v 1 2\n");
        let err = scan_obj("big.obj", &text).err().unwrap().to_string();
        assert!(err.contains("big.obj:1"), "{err}");
    }
}
