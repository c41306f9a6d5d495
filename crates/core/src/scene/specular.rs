//! Specular materials from MTL: `illum`, `Ks`, `Ni`, `d` and `Tr` (the Wavefront MTL
//! illumination models, as in the "MTL material format" of Alias|Wavefront). Why only these:
//! the hybrid eye pass ([`crate::render::specular`]) and the path tracer handle perfect and
//! glossy mirrors and smooth glass, what the radiosity + ray-tracing hybrid was made for
//! (Wallace, Cohen & Greenberg 1987; Sillion & Puech 1989).
//!
//! `illum` 3 or 5 with `Ks` is a mirror reflecting `Ks`: perfect without `Ns` or with `Ns` ≥
//! [`MIRROR_EXPONENT`] (1000, the top of the MTL range), else glossy, a mirror blurred by
//! the Phong lobe of exponent `Ns` around the mirror direction. `illum` 4, 6 or 7, or `d` < 1, or
//! `Tr` > 0, is glass of index `Ni` (default 1.5); anything else is diffuse. A file without
//! these statements, or with the `illum 2`, `Ks`, `Ns` every exporter writes (a highlight
//! for a scanline shader, not a reflection), loads as the purely diffuse scene it always
//! was. `Ni` ≤ 0, `Ns` < 0 and `d`, `Tr` outside [0, 1] are errors naming `file:line`; a
//! mirror whose `Ks + Kd` exceeds 1 in a channel (it would create light) gets `Ks` lowered
//! to `1 − Kd` with a warning.

use glam::DVec3;

use super::{MIRROR_EXPONENT, Rgb, Surface, clamp_reflectance};

/// What one material's specular statements said, for the checks that need several of them.
#[derive(Default)]
pub(super) struct SpecularScan {
    pub name: String,
    pub kd: Option<[f64; 3]>,
    pub ks: Option<([f64; 3], usize)>,
    pub illum: Option<(f64, usize)>,
}

impl SpecularScan {
    /// Checks a one-number statement (`Ni`, `d`, `Tr`, `illum`, `Ns`, …) of this material.
    pub fn number(&mut self, key: &str, x: f64, line: usize) -> Result<(), String> {
        match key {
            "Ni" if x <= 0.0 => Err(format!("'Ni' (refractive index) must be positive, got {x}")),
            "Ns" if x < 0.0 => Err(format!(
                "'Ns' (specular exponent) must be 0 or more, got {x}"
            )),
            "d" | "Tr" if !(0.0..=1.0).contains(&x) => Err(format!(
                "'{key}' ({}) must be in [0, 1], got {x}",
                if key == "d" {
                    "opacity"
                } else {
                    "transparency"
                }
            )),
            "illum" if x.fract() != 0.0 || !(0.0..=255.0).contains(&x) => Err(format!(
                "'illum' must be a whole number (an illumination model, 0 to 10), got {x}"
            )),
            "illum" => {
                self.illum = Some((x, line));
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// Warnings for a mirror (`illum` 3 or 5) whose `Ks` is missing or too large.
    pub fn finish(&self, file: &str, warnings: &mut Vec<String>) {
        let Some((illum, illum_line)) = self.illum else {
            return;
        };
        if illum != 3.0 && illum != 5.0 {
            return;
        }
        let name = &self.name;
        match self.ks {
            None => warnings.push(format!(
                "{file}:{illum_line}: '{name}' is a mirror (illum {illum}) without 'Ks': it reflects nothing specularly"
            )),
            Some((ks, line)) => {
                let kd = self.kd.unwrap_or([0.5; 3]);
                if (0..3).any(|c| ks[c] + clamp_reflectance(kd[c]) > 1.0) {
                    warnings.push(format!(
                        "{file}:{line}: Ks + Kd of '{name}' exceeds 1 in a channel (the mirror would create light); Ks lowered to 1 − Kd"
                    ));
                }
            }
        }
    }
}

/// The specular part an MTL material asks for (see the module docs); `Ks` is lowered to
/// `1 − Kd` where the sum would exceed 1 (warned in [`scan_mtl`]).
pub(super) fn surface(m: &tobj::Material, kd: Rgb) -> Surface {
    let illum = m.illumination_model.unwrap_or(0);
    let transparent = m.dissolve.is_some_and(|d| d < 1.0)
        || m.unknown_param
            .get("Tr")
            .and_then(|t| t.parse::<f64>().ok())
            .is_some_and(|t| t > 0.0);
    if matches!(illum, 4 | 6 | 7) || transparent {
        return Surface::Glass {
            ior: m.optical_density.unwrap_or(1.5),
        };
    }
    if matches!(illum, 3 | 5)
        && let Some(ks) = m.specular
    {
        let ks = DVec3::new(ks[0], ks[1], ks[2]).min(DVec3::ONE - kd);
        if ks.max_element() > 0.0 {
            return match m.shininess {
                Some(exponent) if exponent < MIRROR_EXPONENT => Surface::Glossy { ks, exponent },
                _ => Surface::Mirror { ks },
            };
        }
    }
    Surface::Diffuse
}

#[cfg(test)]
mod tests {
    use crate::scene::{LoadOptions, Scene, SceneError, Surface};
    use glam::DVec3;

    const OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl a\nf 1 2 3\n\
        v 0 0 1\nv 1 0 1\nv 1 1 1\nusemtl light\nf 4 5 6\n";

    fn load(mtl_a: &str) -> Result<Scene, SceneError> {
        let mtl = format!("newmtl a\n{mtl_a}\nnewmtl light\nKd 0 0 0\nKe 1 1 1\n");
        Scene::from_obj_str("t.obj", OBJ, &[("m.mtl", &mtl)], &LoadOptions::default())
    }

    fn surface(mtl_a: &str) -> Surface {
        load(mtl_a).expect("loads").materials[0].surface
    }

    #[test]
    fn illum_selects_mirror_and_glass() {
        assert_eq!(
            surface("Kd 0.1 0.1 0.1\nKs 0.8 0.7 0.6\nillum 3"),
            Surface::Mirror {
                ks: DVec3::new(0.8, 0.7, 0.6)
            }
        );
        assert_eq!(
            surface("Kd 0 0 0\nNi 1.33\nillum 7"),
            Surface::Glass { ior: 1.33 }
        );
        assert_eq!(surface("Kd 0 0 0\nillum 4"), Surface::Glass { ior: 1.5 });
        assert_eq!(
            surface("Kd 0 0 0\nd 0.5\nNi 2.4"),
            Surface::Glass { ior: 2.4 }
        );
        assert_eq!(surface("Kd 0 0 0\nTr 0.5"), Surface::Glass { ior: 1.5 });
    }

    /// `Ns` below 1000 makes a mirror glossy with that exponent; 1000 or more, or none, keeps
    /// it perfect; on a diffuse material (`illum` 2) `Ns` changes nothing.
    #[test]
    fn ns_makes_a_mirror_glossy() {
        let ks = DVec3::new(0.8, 0.7, 0.6);
        assert_eq!(
            surface("Kd 0.1 0.1 0.1\nKs 0.8 0.7 0.6\nNs 40\nillum 3"),
            Surface::Glossy { ks, exponent: 40.0 }
        );
        assert_eq!(
            surface("Kd 0.1 0.1 0.1\nKs 0.8 0.7 0.6\nNs 0\nillum 5"),
            Surface::Glossy { ks, exponent: 0.0 }
        );
        assert_eq!(
            surface("Kd 0.1 0.1 0.1\nKs 0.8 0.7 0.6\nNs 1000\nillum 3"),
            Surface::Mirror { ks }
        );
        assert_eq!(
            surface("Kd 0.1 0.1 0.1\nKs 0.8 0.7 0.6\nNs 40\nillum 2"),
            Surface::Diffuse
        );
    }

    /// What exporters write for plain materials stays diffuse, and the built-in Cornell box
    /// has no specular material.
    #[test]
    fn plain_exporter_materials_stay_diffuse() {
        for m in [
            "Kd 0.8 0.8 0.8\nKs 0.5 0.5 0.5\nNs 250\nNi 1.45\nd 1\nillum 2",
            "Kd 0.8 0.8 0.8\nTr 0\nillum 1",
            "Kd 0.5 0.5 0.5",
        ] {
            let s = load(m).expect("loads");
            assert_eq!(s.materials[0].surface, Surface::Diffuse, "{m}");
            assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        }
        let c = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        assert!(!c.has_specular());
        let s = Scene::builtin("cornell-specular", &LoadOptions::default()).expect("specular");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let kinds: Vec<_> = s.materials.iter().map(|m| m.surface).collect();
        assert!(kinds.contains(&Surface::Glass { ior: 1.5 }));
        assert!(kinds.iter().any(|k| matches!(k, Surface::Mirror { .. })));
        let g = Scene::builtin("cornell-glossy", &LoadOptions::default()).expect("glossy");
        assert!(g.warnings.is_empty(), "{:?}", g.warnings);
        assert!(g.materials.iter().any(|m| matches!(
            m.surface,
            Surface::Glossy { exponent, .. } if exponent == 60.0
        )));
    }

    #[test]
    fn bad_specular_values_name_the_line() {
        for (m, line, what) in [
            ("Kd 0 0 0\nNi 0\nillum 7", 3, "Ni"),
            ("Kd 0 0 0\nNi -1.5", 3, "Ni"),
            ("Kd 0 0 0\nd 1.5", 3, "'d'"),
            ("Tr -0.1", 2, "'Tr'"),
            ("illum 3.5", 2, "illum"),
            ("Ks 0.5 0.5 0.5\nNs -3\nillum 3", 3, "Ns"),
        ] {
            match load(m) {
                Err(SceneError::Parse {
                    file,
                    line: l,
                    message,
                }) => {
                    assert_eq!((file.as_str(), l), ("m.mtl", line), "{m}");
                    assert!(message.contains(what), "{message}");
                }
                other => panic!("{m}: expected a parse error, got {other:?}"),
            }
        }
    }

    /// Ks + Kd > 1 would create light: Ks is lowered to 1 − Kd per channel, with a warning
    /// naming the Ks line.
    #[test]
    fn a_mirror_creating_light_is_clamped_with_a_warning() {
        let s = load("Kd 0.5 0.1 0.1\nKs 0.9 0.9 0.5\nillum 3").expect("loads");
        let Surface::Mirror { ks } = s.materials[0].surface else {
            panic!("not a mirror");
        };
        assert!(
            (ks - DVec3::new(0.5, 0.9, 0.5)).abs().max_element() < 1e-12,
            "{ks}"
        );
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(s.warnings[0].starts_with("m.mtl:3:"), "{}", s.warnings[0]);
        let s = load("Kd 0.5 0.5 0.5\nillum 3").expect("loads");
        assert_eq!(s.materials[0].surface, Surface::Diffuse);
        assert!(s.warnings[0].contains("without 'Ks'"), "{:?}", s.warnings);
    }
}
