//! One memory budget for a whole run.
//!
//! A radiosity run's memory grows with its mesh (elements, display vertices, the BVH,
//! the solver's per-element arrays) and with what the solver stores to save time (cached
//! form-factor rows, a stored matrix, hierarchical links). Without one budget the caches
//! were each bounded on their own, at half the machine's RAM: a million-element Cornell
//! box grew to 12.7 GB and an adaptive run to 13.8 GB before they were stopped. Here the
//! budget is drawn on in a fixed order: the textures and the mesh first (estimated before
//! meshing, so a mesh that cannot fit is refused in seconds with the flag that would make
//! it fit), then the caches get what is left. Caches only save time (a shooting solver
//! recomputes an evicted row), so a small remainder slows a run down but never stops it.
//!
//! The per-element figure is measured, not derived: `/usr/bin/time -v nusselt render
//! --builtin cornell --element-size 1.4 --shots 1 --pass vertex` (993,888 elements) peaks
//! at 800 MB resident, 805 bytes an element with everything a run holds besides its
//! caches; [`ELEMENT_BYTES`] rounds that up for meshing's transient copies.

/// Resident bytes a run holds per element, caches aside (mesh, display vertices and
/// triangles, BVH, solver and render arrays; see the module docs for the measurement).
pub const ELEMENT_BYTES: usize = 1024;

/// Share of what the mesh leaves of the budget that caches may fill; the rest is for what
/// is not counted: the process itself (~30 MB), rows being computed on every thread,
/// the allocator's free lists. Measured: with all of it for the cache an adaptive Cornell
/// run peaked 6 % over `--max-memory 1024` (1,108,448 KB resident).
pub const CACHE_SHARE: f64 = 0.8;

/// Share of the machine's RAM a run may use when not told (`--max-memory`).
pub const DEFAULT_RAM_SHARE: f64 = 0.5;

/// The budget when the machine's RAM cannot be read: 4 GiB.
pub const FALLBACK_BYTES: usize = 4 << 30;

/// Bytes a mesh of `elements` elements costs the run ([`ELEMENT_BYTES`] each).
pub fn mesh_bytes(elements: usize) -> usize {
    elements.saturating_mul(ELEMENT_BYTES)
}

/// The most elements whose mesh fits in `budget` bytes after `held` bytes (textures).
pub fn elements_within(budget: usize, held: usize) -> usize {
    budget.saturating_sub(held) / ELEMENT_BYTES
}

/// The default budget: [`DEFAULT_RAM_SHARE`] of the machine's RAM, or [`FALLBACK_BYTES`]
/// where it cannot be read.
pub fn default_bytes() -> usize {
    machine_memory_bytes().map_or(FALLBACK_BYTES, |b| (b as f64 * DEFAULT_RAM_SHARE) as usize)
}

/// Mebibytes, rounded up, for messages.
pub fn mib(bytes: usize) -> usize {
    bytes.div_ceil(1 << 20)
}

/// The machine's physical RAM in bytes: `/proc/meminfo` on Linux, `sysctl hw.memsize` on
/// macOS and the BSDs; `None` elsewhere or when it cannot be read.
pub fn machine_memory_bytes() -> Option<usize> {
    if let Ok(text) = std::fs::read_to_string("/proc/meminfo") {
        return meminfo_total(&text);
    }
    let out = std::process::Command::new("sysctl")
        .args(["-n", "hw.memsize"])
        .output()
        .ok()?;
    String::from_utf8(out.stdout).ok()?.trim().parse().ok()
}

/// `MemTotal` of a `/proc/meminfo` text, in bytes.
fn meminfo_total(text: &str) -> Option<usize> {
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_is_read_in_kibibytes() {
        let text = "MemTotal:       24576000 kB\nMemFree:        1000 kB\n";
        assert_eq!(meminfo_total(text), Some(24_576_000 * 1024));
        assert_eq!(meminfo_total("MemFree: 3 kB\n"), None);
    }

    #[test]
    fn elements_fit_after_what_is_held() {
        assert_eq!(elements_within(10 * ELEMENT_BYTES, 0), 10);
        assert_eq!(elements_within(10 * ELEMENT_BYTES, 4 * ELEMENT_BYTES), 6);
        assert_eq!(elements_within(ELEMENT_BYTES, 2 * ELEMENT_BYTES), 0);
        assert_eq!(mesh_bytes(usize::MAX), usize::MAX);
    }

    #[test]
    fn this_machine_has_some_memory() {
        // Linux CI reads /proc/meminfo; elsewhere the fallback applies.
        assert!(default_bytes() >= 64 << 20);
    }
}
