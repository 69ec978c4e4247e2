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
    /// The run ended, but an output file could not be written (`message` says which);
    /// `results` hold its outcome (its summary says whether it converged or was stopped).
    #[error("{message}")]
    Output {
        path: PathBuf,
        message: String,
        results: Box<Results>,
    },
    /// The run cannot be carried out as asked: its output directory holds another run's results
    /// or cannot be prepared, a checkpoint does not fit the scenario or this run, or an MPI
    /// launcher started several processes for a solver that is not distributed.
    #[error("{0}")]
    Refused(String),
    /// The MPI ranks of a distributed run could not work together (a collective call failed, a
    /// rank's part of the plan could not be made).
    #[error("{0}")]
    Ranks(String),
    /// Another MPI rank found the fault and reports it; this rank stays silent. `input`: the
    /// fault is of the input's kind ([`Error::Input`], [`Error::Refused`]), else of the ranks'
    /// ([`Error::Ranks`]).
    #[error("another MPI rank failed (its message is on that rank)")]
    OtherRank { input: bool },
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
            Error::Solve { results, .. }
            | Error::Interrupted { results, .. }
            | Error::Output { results, .. } => Some(results),
            _ => None,
        }
    }
}

impl From<InputError> for Error {
    fn from(e: InputError) -> Self {
        Error::Input(e)
    }
}
