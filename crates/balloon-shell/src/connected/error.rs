//! The error of connected balloons ([`super::ConnectedBalloons`]).

use thiserror::Error;

use crate::ShellError;

/// Errors of the connected balloons (`ConnectedBalloons`).
#[derive(Debug, Error)]
pub enum ConnectedError {
    /// No balloons were given.
    #[error("connected balloons: no balloons")]
    Empty,
    /// A balloon does not hold an isothermal ideal gas (the flow moves amounts of gas).
    #[error("balloon {balloon}: connected balloons need the isothermal ideal gas (`gas` = ideal)")]
    NotIdealGas {
        /// The balloon's index.
        balloon: usize,
    },
    /// The balloons do not share the time step or the ambient pressure.
    #[error("balloon {balloon}: `{what}` = {value} differs from balloon 0's {expected}")]
    Mismatch {
        /// The balloon's index.
        balloon: usize,
        /// `"dt"` or `"ambient_pressure"`.
        what: &'static str,
        /// Its value.
        value: f64,
        /// Balloon 0's value.
        expected: f64,
    },
    /// A balloon index beyond the balloons.
    #[error("connected balloons: there is no balloon {balloon} (there are {count})")]
    NoBalloon {
        /// The index asked for.
        balloon: usize,
        /// How many balloons there are.
        count: usize,
    },
    /// A snapshot of another number of balloons ([`super::ConnectedBalloons::restore`]).
    #[error("connected balloons: a snapshot of {snapshot} balloons does not fit these {count}")]
    SnapshotMismatch {
        /// Balloons in the snapshot.
        snapshot: usize,
        /// Balloons here.
        count: usize,
    },
    /// A tube is invalid.
    #[error("tube {tube}: {reason}")]
    InvalidTube {
        /// The tube's index.
        tube: usize,
        /// What is wrong.
        reason: String,
    },
    /// A balloon's step failed. That balloon is rolled back to the start of the step, but the
    /// balloons before it have taken theirs: do not step the set further.
    #[error("balloon {balloon}: {source}")]
    Shell {
        /// The balloon's index.
        balloon: usize,
        /// What failed.
        #[source]
        source: ShellError,
    },
    /// The flow update produced an amount that is not positive and finite.
    #[error("step {step}: the gas flow left balloon {balloon} with amount {amount:e} J")]
    Flow {
        /// Step number (1-based).
        step: usize,
        /// The balloon's index.
        balloon: usize,
        /// Its amount `nRT`, J.
        amount: f64,
    },
}
