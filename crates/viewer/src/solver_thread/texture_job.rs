//! The texture array built beside the solve: resampling and mip-mapping a large model's
//! diffuse maps takes longer than meshing it (1.7 s for the Crytek atrium's 23 maps on two
//! cores), so the first snapshot goes out untextured (each element in its texture's mean
//! colour, as the solver sees it) and the layers follow when ready. The job starts once that
//! first snapshot is out: on two cores its thread would otherwise delay it.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::Instant;

use nusselt_core::scene::Scene;

use super::worker::Worker;
use crate::textures::TextureLayers;

/// A texture array being built for the scene of revision `scene_rev`.
pub(super) struct TextureJob {
    scene_rev: u64,
    rx: Receiver<Option<TextureLayers>>,
}

impl TextureJob {
    /// Starts building `scene`'s layers on a thread of their own; `None` for a scene
    /// without diffuse maps.
    pub(super) fn start(scene: &Scene, scene_rev: u64) -> Option<TextureJob> {
        if scene.textures.is_empty() {
            return None;
        }
        let (textures, materials) = (scene.textures.clone(), scene.materials.clone());
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let spawned = std::thread::Builder::new()
            .name("nusselt textures".into())
            .spawn(move || {
                let started = Instant::now();
                let layers = TextureLayers::build_from(&textures, &materials);
                if let Some(t) = &layers {
                    eprintln!(
                        "viewer: {} texture layers of {}² ({} mips), {:.1} MB on the GPU, prepared in {:.2} s",
                        t.layers,
                        t.size,
                        t.mip_levels,
                        t.gpu_bytes() as f64 / 1e6,
                        started.elapsed().as_secs_f64()
                    );
                }
                // The worker may have gone (the viewer closed): nothing to tell.
                let _ = tx.send(layers);
            });
        match spawned {
            Ok(_) => Some(TextureJob { scene_rev, rx }),
            Err(e) => {
                eprintln!("viewer: cannot start the texture thread ({e}); drawing untextured");
                None
            }
        }
    }
}

impl Worker {
    /// Takes the texture array if its job is done and still for the scene on screen.
    pub(super) fn poll_textures(&mut self) {
        let Some(job) = &self.texture_job else {
            return;
        };
        match job.rx.try_recv() {
            Ok(layers) => {
                if job.scene_rev == self.scene_rev {
                    self.textures = layers.map(Arc::new);
                    self.dirty = true;
                }
                self.texture_job = None;
            }
            Err(TryRecvError::Empty) => {}
            Err(TryRecvError::Disconnected) => self.texture_job = None,
        }
    }
}
