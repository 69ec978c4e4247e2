//! The one error of the library interface.

use super::results::Results;
use crate::io::scenario::InputError;
use std::path::PathBuf;

/// Why a simulation could not be built or did not finish.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scenario or an override is wrong: the file, the key path where known, and what was
    /// expected.
    #[error("{0}")]
    Input(InputError),
    /// The run started and a stage failed; `results` hold every step accepted before.
    #[error("{reason}")]
    Solve {
        reason: String,
        results: Box<Results>,
    },
    /// A file could not be read or written.
    #[error("{}: {message}", path.display())]
    Io { path: PathBuf, message: String },
    /// The run was stopped on request (a [`super::Cancel`], a signal); `results` hold every
    /// step accepted before.
    #[error("{reason}")]
    Interrupted {
        reason: String,
        results: Box<Results>,
    },
}

impl Error {
    /// The dotted key path of an input error, where known.
    pub fn key(&self) -> Option<&str> {
        match self {
            Error::Input(e) => e.key.as_deref(),
            _ => None,
        }
    }

    /// The results of a run that stopped early (every accepted step), if it started.
    pub fn results(&self) -> Option<&Results> {
        match self {
            Error::Solve { results, .. } | Error::Interrupted { results, .. } => Some(results),
            _ => None,
        }
    }
}

impl From<InputError> for Error {
    fn from(e: InputError) -> Self {
        Error::Input(e)
    }
}
