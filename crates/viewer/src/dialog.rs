//! File dialogs that do not stop the viewport: each dialog runs rfd's
//! [`rfd::AsyncFileDialog`] on its own named thread (`pollster::block_on`), and the chosen
//! path comes back through a bounded channel, with a repaint request so the UI picks it up
//! at once. Meanwhile the window keeps drawing and the solver keeps shooting.
//!
//! One dialog at a time: asking for a second while one is open is refused with a message.
//! Without a portal (under Xvfb, say) rfd answers `None` at once, which is "cancelled";
//! a dialog thread that dies without answering is reported, never waited for.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, TryRecvError};

/// What a dialog was opened for (decides what happens with the chosen path).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    Open,
    SaveMtlAs,
    ExportPly,
    ExportGltf,
    ExportPng,
}

/// A file dialog to show.
#[derive(Clone, Debug)]
pub struct Request {
    pub purpose: Purpose,
    /// Filter name and extensions (without dots).
    pub filter: (String, Vec<String>),
    /// A save dialog (otherwise: pick an existing file).
    pub save: bool,
    pub file_name: Option<String>,
    pub directory: Option<PathBuf>,
}

impl Request {
    /// A dialog with one filter (`(name, extensions)`, extensions comma-separated), no
    /// default name or folder.
    pub fn new(purpose: Purpose, filter: (&str, &str), save: bool) -> Request {
        Request {
            purpose,
            filter: (
                filter.0.to_string(),
                filter.1.split(',').map(str::to_string).collect(),
            ),
            save,
            file_name: None,
            directory: None,
        }
    }

    /// Shows the dialog and waits for it (on the dialog thread).
    fn show(self) -> Option<PathBuf> {
        let mut dialog = rfd::AsyncFileDialog::new().add_filter(self.filter.0, &self.filter.1);
        if let Some(dir) = self.directory {
            dialog = dialog.set_directory(dir);
        }
        if let Some(name) = self.file_name {
            dialog = dialog.set_file_name(name);
        }
        let picked = if self.save {
            pollster::block_on(dialog.save_file())
        } else {
            pollster::block_on(dialog.pick_file())
        };
        picked.map(|f| f.path().to_path_buf())
    }
}

/// What [`Dialogs::poll`] found.
#[derive(Debug, PartialEq)]
pub enum Outcome {
    /// The user chose this path.
    Chosen(Purpose, PathBuf),
    /// The dialog closed without a path (cancelled, or no portal).
    Cancelled(Purpose),
    /// The dialog thread ended without an answer (it panicked).
    Failed(Purpose),
}

/// The open dialog, if any.
#[derive(Default)]
pub struct Dialogs {
    open: Option<(Purpose, Receiver<Option<PathBuf>>)>,
}

impl Dialogs {
    /// Opens `request` in rfd on a dialog thread; `wake` is called when it answers.
    pub fn open(
        &mut self,
        request: Request,
        wake: impl Fn() + Send + 'static,
    ) -> Result<(), String> {
        let purpose = request.purpose;
        self.run(purpose, move || request.show(), wake)
    }

    /// Runs `show` (a dialog, or a stand-in in tests) on a named thread.
    pub fn run(
        &mut self,
        purpose: Purpose,
        show: impl FnOnce() -> Option<PathBuf> + Send + 'static,
        wake: impl Fn() + Send + 'static,
    ) -> Result<(), String> {
        if self.open.is_some() {
            return Err("a file dialog is already open".into());
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        std::thread::Builder::new()
            .name("nusselt-dialog".into())
            .spawn(move || {
                let picked = show();
                // The receiver is gone only if the app is closing.
                let _ = tx.send(picked);
                wake();
            })
            .map_err(|e| format!("cannot open a file dialog: {e}"))?;
        self.open = Some((purpose, rx));
        Ok(())
    }

    /// Whether a dialog is open.
    pub fn is_open(&self) -> bool {
        self.open.is_some()
    }

    /// The dialog's answer, if it has one (never waits).
    pub fn poll(&mut self) -> Option<Outcome> {
        let (purpose, rx) = self.open.as_ref()?;
        let purpose = *purpose;
        let outcome = match rx.try_recv() {
            Ok(Some(path)) => Outcome::Chosen(purpose, path),
            Ok(None) => Outcome::Cancelled(purpose),
            Err(TryRecvError::Empty) => return None,
            Err(TryRecvError::Disconnected) => Outcome::Failed(purpose),
        };
        self.open = None;
        Some(outcome)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::{Duration, Instant};

    use super::*;

    fn wait(d: &mut Dialogs) -> Outcome {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(o) = d.poll() {
                return o;
            }
            assert!(
                Instant::now() < deadline,
                "no answer from the dialog thread"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn answers_arrive_without_blocking_the_caller() {
        let mut d = Dialogs::default();
        let wakes = Arc::new(AtomicUsize::new(0));
        let w = wakes.clone();
        let (release, gate) = std::sync::mpsc::sync_channel::<()>(1);
        d.run(
            Purpose::Open,
            move || {
                // A user taking their time: the caller must not wait for this.
                gate.recv().ok();
                Some(PathBuf::from("room.obj"))
            },
            move || {
                w.fetch_add(1, Ordering::Relaxed);
            },
        )
        .expect("run");
        assert_eq!(d.poll(), None, "poll must not wait for the dialog");
        assert!(d.is_open());
        assert!(
            d.run(Purpose::ExportPly, || None, || {}).is_err(),
            "a second dialog while one is open"
        );
        release.send(()).expect("release");
        assert_eq!(
            wait(&mut d),
            Outcome::Chosen(Purpose::Open, PathBuf::from("room.obj"))
        );
        assert_eq!(wakes.load(Ordering::Relaxed), 1, "the UI is woken once");
        assert!(!d.is_open());
        d.run(Purpose::SaveMtlAs, || None, || {}).expect("run");
        assert_eq!(wait(&mut d), Outcome::Cancelled(Purpose::SaveMtlAs));
    }

    #[test]
    fn a_dialog_thread_that_panics_is_reported_not_waited_for() {
        let mut d = Dialogs::default();
        d.run(Purpose::ExportPng, || panic!("the portal went away"), || {})
            .expect("run");
        assert_eq!(wait(&mut d), Outcome::Failed(Purpose::ExportPng));
        assert!(!d.is_open(), "a new dialog can be opened after a failure");
    }

    /// Under Xvfb and in CI there is no desktop portal: rfd must answer "nothing chosen"
    /// promptly, not hang and not panic.
    #[test]
    fn without_a_portal_a_real_dialog_answers_nothing() {
        if std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some() {
            eprintln!("skipped: a D-Bus session bus is set, a real dialog could open");
            return;
        }
        let mut d = Dialogs::default();
        d.open(
            Request::new(Purpose::Open, ("Wavefront OBJ", "obj"), false),
            || {},
        )
        .expect("open");
        assert_eq!(wait(&mut d), Outcome::Cancelled(Purpose::Open));
    }
}
