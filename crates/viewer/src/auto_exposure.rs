//! A first view that is neither black nor white ([`auto_exposure_stops`]): a scene whose
//! lights are weak for its size (glTF lights in photometric units, a model in millimetres
//! lit by a 1 W point) shows nothing at exposure 0, one lit by a strong light (`Ke` 1000
//! behind a door) shows white. Once per scene, on the first snapshot that carries light, the
//! viewer checks the displayed radiance and, if the scene is that dark or bright, sets the
//! exposure so that it is seen, and says so. A scene that is visible at exposure 0 (the
//! Cornell box, most models with their own emitters) keeps 0, and an exposure the user
//! chose (`--exposure`, the slider) is never changed.

use nusselt_core::render::image::auto_exposure_stops;

/// The state of the automatic exposure for the scene on screen.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AutoExposure {
    /// Waiting for the first snapshot with light of a scene whose exposure nobody chose.
    pub armed: bool,
    /// The exposure (stops) set automatically, while it is still what the panel shows.
    pub applied: Option<f32>,
}

impl AutoExposure {
    /// At start: armed unless an exposure was given.
    pub fn new(exposure_stops: f32) -> Self {
        Self {
            armed: exposure_stops == 0.0,
            applied: None,
        }
    }

    /// A new scene: an automatic exposure of the last one goes back to 0, and the new
    /// scene is checked unless the user set the exposure.
    pub fn on_new_scene(&mut self, exposure_stops: &mut f32) {
        if self.applied == Some(*exposure_stops) {
            *exposure_stops = 0.0;
        }
        self.applied = None;
        self.armed = *exposure_stops == 0.0;
    }

    /// A snapshot's displayed radiance per vertex: when armed and it carries light, the
    /// exposure is decided (returned when changed, and then written to `exposure_stops`).
    pub fn on_snapshot(&mut self, displayed: &[[f32; 3]], exposure_stops: &mut f32) -> Option<f32> {
        if !self.armed {
            return None;
        }
        let stops = auto_scene_stops(displayed)?;
        self.armed = false;
        if stops == 0.0 {
            return None;
        }
        *exposure_stops = stops;
        self.applied = Some(stops);
        Some(stops)
    }
}

/// [`auto_exposure_stops`] of the displayed radiance per vertex; `None` (not yet) while
/// fewer than 5 % of the vertices show any light: a snapshot before the first light was
/// shot or gathered shows the emitters alone, and exposing for them would darken the scene
/// they are about to light (a gathering solver's first snapshot, before its first sweep).
pub fn auto_scene_stops(displayed: &[[f32; 3]]) -> Option<f32> {
    let lum: Vec<f64> = displayed
        .iter()
        .map(|c| f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]))
        .collect();
    let lit = lum.iter().filter(|l| **l > 0.0).count();
    if lit * 20 < lum.len() {
        return None;
    }
    auto_exposure_stops(lum).map(|s| s as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::render::image::TARGET_LUMINANCE as TARGET;

    /// Only the emitters lit (a gathering solver before its first sweep): wait, whatever
    /// their brightness; once the scene carries light, decide.
    #[test]
    fn the_emitters_alone_do_not_decide_the_exposure() {
        let mut first = vec![[0.0f32; 3]; 100];
        first[0] = [17.0, 12.0, 4.0];
        let mut e = 0.0;
        let mut auto = AutoExposure::new(0.0);
        assert_eq!(auto.on_snapshot(&first, &mut e), None);
        assert!(auto.armed, "still waiting for light on the scene");
        assert_eq!(e, 0.0);
        let lit = vec![[0.3, 0.3, 0.3]; 100];
        assert_eq!(auto.on_snapshot(&lit, &mut e), None);
        assert!(!auto.armed);
        assert_eq!(e, 0.0);
    }

    #[test]
    fn a_visible_scene_keeps_exposure_zero() {
        let lit = vec![[0.3, 0.3, 0.3]; 100];
        assert_eq!(auto_scene_stops(&lit), Some(0.0));
        let mut e = 0.0;
        let mut auto = AutoExposure::new(0.0);
        assert_eq!(auto.on_snapshot(&lit, &mut e), None);
        assert_eq!(e, 0.0);
        assert!(!auto.armed);
    }

    /// 1/256 of the target: 8 stops; 1/100: log2(100) = 6.64 → 6.5 (half stops, rounded
    /// down so the brightest stay in range).
    #[test]
    fn a_dark_scene_is_brought_to_the_target() {
        assert_eq!(
            auto_scene_stops(&vec![[TARGET as f32 / 256.0; 3]; 50]),
            Some(8.0)
        );
        assert_eq!(
            auto_scene_stops(&vec![[0.01 * TARGET as f32; 3]; 50]),
            Some(6.5)
        );
        // Darker than the slider reaches: its end.
        assert_eq!(auto_scene_stops(&vec![[1e-9; 3]; 50]), Some(8.0));
    }

    /// A room lit through a door by `Ke` 1000 shows white at 0: brought down to the target.
    #[test]
    fn a_burnt_out_scene_is_brought_down() {
        assert_eq!(
            auto_scene_stops(&vec![[64.0 * TARGET as f32; 3]; 50]),
            Some(-6.0)
        );
        assert_eq!(auto_scene_stops(&vec![[1e9; 3]; 50]), Some(-8.0));
    }

    #[test]
    fn nothing_lit_waits_and_a_chosen_exposure_is_kept() {
        let mut e = 0.0;
        let mut auto = AutoExposure::new(0.0);
        assert_eq!(auto.on_snapshot(&[[0.0; 3]; 10], &mut e), None);
        assert!(auto.armed, "still waiting for light");
        assert_eq!(auto.on_snapshot(&[[0.001; 3]; 10], &mut e), Some(8.0));
        assert_eq!(e, 8.0);
        // The next scene starts from 0 again, and is visible.
        auto.on_new_scene(&mut e);
        assert_eq!(e, 0.0);
        assert!(auto.armed);
        // A user's exposure is never touched.
        let mut chosen = -1.0;
        let mut auto = AutoExposure::new(chosen);
        assert_eq!(auto.on_snapshot(&[[0.001; 3]; 10], &mut chosen), None);
        assert_eq!(chosen, -1.0);
    }
}
