//! The `nusselt` binary: the command-line interface and the bench harness, on top of the
//! core (`nusselt-core`), the GPU hemicube (`nusselt-gpu`) and the viewer (`nusselt-viewer`).

mod cli;

fn main() -> std::process::ExitCode {
    match cli::main() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
