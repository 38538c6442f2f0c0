//! The one error of every command, and the one place exit codes are decided
//! (SPEC 6.4: 0 valid or clean, 1 a run failed, 2 usage or document errors).

use crate::executable::ExecutableError;

/// Exit codes.
pub mod exit {
    /// Everything valid, or a clean stop.
    pub const OK: u8 = 0;
    /// A build or an instance failed, or a restart budget ran out.
    pub const FAILED: u8 = 1;
    /// A document, binding or command line is invalid.
    pub const INVALID: u8 = 2;
    /// Stopped by Ctrl-C before it was done (128 + SIGINT, as shells do).
    pub const INTERRUPTED: u8 = 130;
}

/// Why a command did not succeed.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// Documents, bindings or parameters are invalid. Their located
    /// diagnostics were already printed, for people or as JSON.
    #[error("invalid: {errors} error(s), reported above")]
    Invalid {
        /// How many errors were reported.
        errors: usize,
    },
    /// A command-line value is invalid.
    #[error("{0}")]
    Usage(String),
    /// The node's start-up inputs (`--bind`, parameters, instance id) were
    /// refused by the same rules the node applies.
    #[error(transparent)]
    Startup(#[from] peppy_runtime::Error),
    /// A node's build failed or its program cannot be found.
    #[error(transparent)]
    Build(#[from] ExecutableError),
    /// The launch could not set itself up (runtime, run directory, ports,
    /// router).
    #[error("{0}")]
    Setup(String),
    /// An instance failed or used up its restart budget; the output above
    /// names it and its log.
    #[error("an instance failed")]
    InstanceFailed,
    /// A running stack did not give what an inspection command asked for:
    /// a call failed, a goal was rejected, fewer messages than `--count`
    /// arrived in time.
    #[error("{0}")]
    Inspect(String),
    /// Ctrl-C stopped a command that had nothing to finish cleanly.
    #[error("interrupted")]
    Interrupted,
}

impl LaunchError {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            LaunchError::Invalid { .. } | LaunchError::Usage(_) | LaunchError::Startup(_) => {
                exit::INVALID
            }
            LaunchError::Build(_)
            | LaunchError::Setup(_)
            | LaunchError::InstanceFailed
            | LaunchError::Inspect(_) => exit::FAILED,
            LaunchError::Interrupted => exit::INTERRUPTED,
        }
    }

    /// Whether the command already told the user everything (the
    /// diagnostics, or the failed instance's story), so printing the error
    /// again would only repeat it.
    pub fn already_reported(&self) -> bool {
        matches!(
            self,
            LaunchError::Invalid { .. } | LaunchError::InstanceFailed
        )
    }
}

/// What a command returns.
pub type Result<T = ()> = std::result::Result<T, LaunchError>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_follow_the_kind_of_failure() {
        assert_eq!(LaunchError::Invalid { errors: 3 }.exit_code(), 2);
        assert_eq!(LaunchError::Usage("x".into()).exit_code(), 2);
        assert_eq!(
            LaunchError::Startup(peppy_runtime::Error::Startup("x".into())).exit_code(),
            2
        );
        assert_eq!(LaunchError::Setup("x".into()).exit_code(), 1);
        assert_eq!(LaunchError::InstanceFailed.exit_code(), 1);
        assert!(LaunchError::InstanceFailed.already_reported());
        assert!(!LaunchError::Setup("x".into()).already_reported());
        assert_eq!(LaunchError::Interrupted.exit_code(), 130);
    }
}
