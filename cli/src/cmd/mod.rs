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

/// `err` with its causes, each said once. The libraries' errors end their message with their
/// source's (so a caller printing only the message loses nothing) and keep it as `source()`;
/// anyhow's `{:#}` would print such a cause twice.
pub fn describe(err: &anyhow::Error) -> String {
    let mut text = err.to_string();
    for cause in err.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}

/// A closed stdout (`intellwheels ... | head`) is a clean stop, not an error.
pub fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_the_message_already_says_is_said_once() {
        let dir = std::env::temp_dir().join(format!("iw-describe-{}", std::process::id()));
        let key = dir.join("no-such-dir").join("key.pk8");
        let node = iw_node::write_identity(&key).unwrap_err();
        let io = std::error::Error::source(&node)
            .expect("the OS error")
            .to_string();
        let err = anyhow::Error::from(node).context("writing the deployment's keys");
        let text = describe(&err);
        assert!(
            text.starts_with("writing the deployment's keys: identity key "),
            "{text}"
        );
        assert_eq!(text.matches(&io).count(), 1, "{text}");
        // anyhow's own chain says the OS error twice: once in the message, once as the cause
        assert_eq!(format!("{err:#}").matches(&io).count(), 2);
    }
}
