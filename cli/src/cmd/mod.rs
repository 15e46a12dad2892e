//! One module per subcommand; each exposes its clap type and a `run` returning the exit code.

pub mod acl;
pub mod bench;
mod bench_drive;
mod bench_fleet;
pub mod demo;
pub mod experiment;
pub mod features;
pub mod flags;
pub mod impair;
pub mod log;
pub mod repeatability;
pub mod scenario;
pub mod sl;
pub mod spawn;
pub mod vo;

/// A closed stdout (`intellwheels ... | head`) is a clean stop, not an error.
pub fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
