//! MTL texture-map statements (`map_Kd`, `map_d`): their options, finding the image file,
//! and reading each distinct image once, in parallel.
//!
//! Files written on Windows name textures with backslashes (`textures\wall.tga`) and often
//! in another case than on disk (`KAMEN-stup.png` for `kamen-stup.png`), so a path is tried
//! as written (backslashes as separators), then case-insensitively one component at a time,
//! then by its file name alone next to the MTL file.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use glam::DVec2;
use rayon::prelude::*;

use super::texture::{Texture, TextureId, TextureKind};

/// The MTL map options: name, how many words each takes (at most, for numbers), and
/// whether those are numbers.
const OPTIONS: &[(&str, usize, bool)] = &[
    ("-blendu", 1, false),
    ("-blendv", 1, false),
    ("-bm", 1, true),
    ("-boost", 1, true),
    ("-cc", 1, false),
    ("-clamp", 1, false),
    ("-imfchan", 1, false),
    ("-mm", 2, true),
    ("-o", 3, true),
    ("-s", 3, true),
    ("-t", 3, true),
    ("-texres", 1, true),
    ("-type", 1, false),
];

/// `uv ↦ uv · scale + offset`: a map's `-s` and `-o` options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub scale: DVec2,
    pub offset: DVec2,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform {
            scale: DVec2::ONE,
            offset: DVec2::ZERO,
        }
    }
}

impl UvTransform {
    pub fn apply(&self, uv: DVec2) -> DVec2 {
        uv * self.scale + self.offset
    }
}

/// A parsed `map_*` statement: the file name, its `-s`/`-o` transform, and the options
/// that are ignored.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MapStatement {
    pub name: String,
    pub transform: UvTransform,
    pub ignored: Vec<String>,
}

/// Parses the words after `map_Kd`/`map_d`; `Err` when no file name is left.
pub(super) fn parse_map(args: &[&str]) -> Result<MapStatement, String> {
    let mut transform = UvTransform::default();
    let mut ignored = Vec::new();
    let mut i = 0;
    while let Some(&(opt, most, numeric)) = args
        .get(i)
        .and_then(|w| OPTIONS.iter().find(|(o, _, _)| o == w))
    {
        i += 1;
        let mut values = Vec::new();
        // The last word is the file name.
        while values.len() < most && i + 1 < args.len() {
            let v = if numeric {
                args[i].parse::<f64>().ok()
            } else {
                Some(f64::NAN)
            };
            let Some(v) = v else { break };
            values.push(v);
            i += 1;
        }
        match (opt, values.as_slice()) {
            ("-s", [u, rest @ ..]) => {
                transform.scale = DVec2::new(*u, rest.first().copied().unwrap_or(1.0))
            }
            ("-o", [u, rest @ ..]) => {
                transform.offset = DVec2::new(*u, rest.first().copied().unwrap_or(0.0))
            }
            _ => ignored.push(opt.to_string()),
        }
    }
    let name = args.get(i..).unwrap_or_default().join(" ");
    if name.is_empty() {
        return Err("a texture map needs a file name".into());
    }
    Ok(MapStatement {
        name,
        transform,
        ignored,
    })
}

/// The image file a map names, relative to the MTL file's folder `mtl_dir`: as written
/// (Windows backslashes read as separators), else matching each missing path component
/// case-insensitively, else the file name alone in `mtl_dir` (case-insensitively).
pub fn resolve_texture_path(mtl_dir: &Path, name: &str) -> Option<PathBuf> {
    let name = name.trim().replace('\\', "/");
    if name.is_empty() {
        return None;
    }
    let rel = Path::new(&name);
    let exact = mtl_dir.join(rel);
    if exact.is_file() {
        return Some(exact);
    }
    if let Some(p) = case_insensitive(mtl_dir, rel).filter(|p| p.is_file()) {
        return Some(p);
    }
    let file = rel.file_name()?;
    case_insensitive(mtl_dir, Path::new(file)).filter(|p| p.is_file())
}

/// `base` joined with `rel`, each component that does not exist replaced by the entry of
/// its folder equal to it ignoring case (the first by name if several are).
fn case_insensitive(base: &Path, rel: &Path) -> Option<PathBuf> {
    let mut at = base.to_path_buf();
    for c in rel.components() {
        match c {
            Component::Normal(part) => {
                let next = at.join(part);
                at = if next.exists() {
                    next
                } else {
                    find_ignoring_case(&at, &part.to_string_lossy())?
                };
            }
            other => at.push(other.as_os_str()),
        }
    }
    Some(at)
}

fn find_ignoring_case(dir: &Path, part: &str) -> Option<PathBuf> {
    let want = part.to_lowercase();
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().to_lowercase() == want)
        .map(|e| e.path())
        .collect();
    found.sort();
    found.into_iter().next()
}

/// Which material slot a map fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Slot {
    /// `map_Kd`
    Diffuse,
    /// `map_d`
    Alpha,
}

impl Slot {
    pub fn keyword(self) -> &'static str {
        match self {
            Slot::Diffuse => "map_Kd",
            Slot::Alpha => "map_d",
        }
    }

    fn kind(self) -> TextureKind {
        match self {
            Slot::Diffuse => TextureKind::Color,
            Slot::Alpha => TextureKind::Mask,
        }
    }
}

/// A map a material used by some face asks for.
#[derive(Clone, Debug)]
pub(super) struct MapRequest {
    pub material: usize,
    pub slot: Slot,
    pub name: String,
    /// The MTL file as displayed (its folder is where `name` is looked up).
    pub mtl_file: String,
    pub line: usize,
}

/// What [`load_maps`] read: the textures, and per request its texture (or none).
pub(super) struct LoadedMaps {
    pub textures: Vec<Arc<Texture>>,
    pub assigned: Vec<Option<TextureId>>,
    pub warnings: Vec<String>,
}

/// Maps read ahead of the requests that will ask for them ([`preload`]), by resolved path
/// and kind.
pub(super) type Preloaded = HashMap<(PathBuf, TextureKind), Result<Texture, String>>;

/// Reads the maps `requests` resolve to, each distinct (file, kind) once, in parallel, for
/// [`load_maps`] to take instead of reading them again. Files that do not resolve are left
/// to it (it warns).
pub(super) fn preload(requests: &[MapRequest]) -> Preloaded {
    let mut keys: Vec<(PathBuf, TextureKind)> = Vec::new();
    for r in requests {
        let dir = Path::new(&r.mtl_file).parent().unwrap_or(Path::new(""));
        if let Some(p) = resolve_texture_path(dir, &r.name) {
            let key = (p, r.slot.kind());
            if !keys.contains(&key) {
                keys.push(key);
            }
        }
    }
    keys.into_par_iter()
        .map(|(p, kind)| {
            let read = read_image(&p, kind);
            ((p, kind), read)
        })
        .collect()
}

/// Resolves and reads the requested maps, each distinct (file, kind) once, in parallel
/// (taken from `preloaded` where it has them). A missing or unreadable file is a warning
/// naming the MTL line and the path tried.
pub(super) fn load_maps(requests: &[MapRequest], mut preloaded: Preloaded) -> LoadedMaps {
    let mut warnings = Vec::new();
    let mut keys: Vec<(PathBuf, TextureKind)> = Vec::new();
    let mut key_of: HashMap<(PathBuf, TextureKind), usize> = HashMap::new();
    let mut request_key = Vec::with_capacity(requests.len());
    let mut missing: Vec<(PathBuf, Vec<&MapRequest>)> = Vec::new();
    for r in requests {
        let dir = Path::new(&r.mtl_file).parent().unwrap_or(Path::new(""));
        match resolve_texture_path(dir, &r.name) {
            Some(p) => {
                let key = (p, r.slot.kind());
                let k = *key_of.entry(key.clone()).or_insert_with(|| {
                    keys.push(key);
                    keys.len() - 1
                });
                request_key.push(Some(k));
            }
            None => {
                let tried = dir.join(r.name.replace('\\', "/"));
                match missing.iter_mut().find(|(p, _)| *p == tried) {
                    Some((_, rs)) => rs.push(r),
                    None => missing.push((tried, vec![r])),
                }
                request_key.push(None);
            }
        }
    }
    for (tried, rs) in &missing {
        warnings.push(problem(
            rs,
            &format!("texture not found (tried {})", tried.display()),
        ));
    }
    let mut ahead: Vec<Option<Result<Texture, String>>> =
        keys.iter().map(|k| preloaded.remove(k)).collect();
    drop(preloaded);
    let read: Vec<Result<Texture, String>> = (keys.par_iter().zip(ahead.par_iter_mut()))
        .map(|((p, kind), ahead)| ahead.take().unwrap_or_else(|| read_image(p, *kind)))
        .collect();
    let mut textures = Vec::new();
    let mut id_of_key = vec![None; keys.len()];
    for (k, result) in read.into_iter().enumerate() {
        match result {
            Ok(t) => {
                id_of_key[k] = Some(TextureId(textures.len() as u32));
                textures.push(Arc::new(t));
            }
            Err(e) => {
                let rs: Vec<&MapRequest> = requests
                    .iter()
                    .zip(&request_key)
                    .filter(|(_, key)| **key == Some(k))
                    .map(|(r, _)| r)
                    .collect();
                let what = format!("cannot read texture {}: {e}", keys[k].0.display());
                warnings.push(problem(&rs, &what));
            }
        }
    }
    let assigned = request_key
        .iter()
        .map(|k| k.and_then(|k| id_of_key[k]))
        .collect();
    LoadedMaps {
        textures,
        assigned,
        warnings,
    }
}

/// Reads one image; a decoder that panics on a corrupt file is an error too.
fn read_image(path: &Path, kind: TextureKind) -> Result<Texture, String> {
    std::panic::catch_unwind(|| Texture::load(path, kind))
        .unwrap_or_else(|_| Err("the image decoder failed on this file".into()))
}

/// One warning for a file several requests share: the first one's MTL line, the others
/// counted.
fn problem(rs: &[&MapRequest], what: &str) -> String {
    let r = rs[0];
    let more = match rs.len() {
        1 => String::new(),
        n => format!(" (and {} more material(s))", n - 1),
    };
    let fallback = match r.slot {
        Slot::Diffuse => "the material keeps its Kd",
        Slot::Alpha => "the material stays opaque",
    };
    format!(
        "{}:{}: {} of '{}': {what}; {fallback}{more}",
        r.mtl_file,
        r.line,
        r.slot.keyword(),
        r.name
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<MapStatement, String> {
        parse_map(&s.split_whitespace().collect::<Vec<_>>())
    }

    #[test]
    fn options_are_applied_or_listed_as_ignored() {
        let m = parse("-s 2 3 1 -o 0.5 0.25 0 -clamp on -bm 0.4 tex\\wall 1.png").expect("parses");
        assert_eq!(m.name, "tex\\wall 1.png");
        assert_eq!(m.transform.scale, DVec2::new(2.0, 3.0));
        assert_eq!(m.transform.offset, DVec2::new(0.5, 0.25));
        assert_eq!(m.ignored, ["-clamp", "-bm"]);
        assert_eq!(
            m.transform.apply(DVec2::new(1.0, 1.0)),
            DVec2::new(2.5, 3.25)
        );
        let m = parse("-s 4 wall.png").expect("parses");
        assert_eq!(m.transform.scale, DVec2::new(4.0, 1.0));
        assert_eq!(
            parse("wall.png").expect("parses").transform,
            UvTransform::default()
        );
        // The last word is the file name even when it looks like a number.
        assert_eq!(parse("-o 1 2").expect("parses").name, "2");
        assert!(parse("").is_err());
        assert!(parse("-clamp").is_err());
    }

    #[test]
    fn paths_resolve_backslashes_case_and_bare_names() {
        let dir = tempfile::tempdir().expect("temp dir");
        let sub = dir.path().join("Textures");
        std::fs::create_dir(&sub).expect("mkdir");
        std::fs::write(sub.join("Wall.PNG"), b"x").expect("write");
        std::fs::write(dir.path().join("floor.tga"), b"x").expect("write");
        let want = Some(sub.join("Wall.PNG"));
        for name in [
            "Textures/Wall.PNG",
            "Textures\\Wall.PNG",
            "textures\\wall.png",
            " TEXTURES/wall.Png ",
        ] {
            assert_eq!(resolve_texture_path(dir.path(), name), want, "{name}");
        }
        // An absolute path from the author's machine: the file name next to the MTL.
        let floor = Some(dir.path().join("floor.tga"));
        assert_eq!(
            resolve_texture_path(dir.path(), "C:\\Users\\me\\maps\\Floor.TGA"),
            floor
        );
        assert_eq!(resolve_texture_path(dir.path(), "missing.png"), None);
        assert_eq!(resolve_texture_path(dir.path(), "Textures"), None);
        assert_eq!(resolve_texture_path(dir.path(), ""), None);
    }
}
