//! Where a solve's time goes: wall-clock time split by phase, for the static solver
//! ([`crate::statics::StaticInfo::times`]) and the backward-Euler step
//! ([`crate::implicit::StepInfo::times`], [`crate::implicit::BackwardEuler::phase_times`]).

use std::time::Instant;

use serde::{Deserialize, Serialize};

/// Wall-clock time of a solve split by phase, ms: where a Newton iteration's time goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PhaseTimes {
    /// Force evaluations: the element forces with their stiffness blocks, the gas term.
    pub forces_ms: f64,
    /// Energy evaluations of the line search.
    pub energy_ms: f64,
    /// Stiffness collection and sparse assembly of the Newton matrix.
    pub assembly_ms: f64,
    /// Numeric sparse factorisations (with their symbolic analyses).
    pub factorization_ms: f64,
    /// Linear solves without their factorisations (triangular solves, CG iterations).
    pub solve_ms: f64,
    /// Shell-volume projections (filled by callers that project; 0 in the integrators).
    pub projection_ms: f64,
}

impl PhaseTimes {
    /// The sum of the phases, ms.
    pub fn total_ms(&self) -> f64 {
        self.forces_ms
            + self.energy_ms
            + self.assembly_ms
            + self.factorization_ms
            + self.solve_ms
            + self.projection_ms
    }
}

impl std::ops::AddAssign for PhaseTimes {
    fn add_assign(&mut self, o: Self) {
        self.forces_ms += o.forces_ms;
        self.energy_ms += o.energy_ms;
        self.assembly_ms += o.assembly_ms;
        self.factorization_ms += o.factorization_ms;
        self.solve_ms += o.solve_ms;
        self.projection_ms += o.projection_ms;
    }
}

impl std::ops::Sub for PhaseTimes {
    type Output = Self;

    /// The time spent between two readings of a running total (`later - earlier`).
    fn sub(self, o: Self) -> Self {
        Self {
            forces_ms: self.forces_ms - o.forces_ms,
            energy_ms: self.energy_ms - o.energy_ms,
            assembly_ms: self.assembly_ms - o.assembly_ms,
            factorization_ms: self.factorization_ms - o.factorization_ms,
            solve_ms: self.solve_ms - o.solve_ms,
            projection_ms: self.projection_ms - o.projection_ms,
        }
    }
}

impl std::fmt::Display for PhaseTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "forces {:.1}, energy {:.1}, assembly {:.1}, factorisation {:.1}, solves {:.1}, \
             projection {:.1} (sum {:.1} ms)",
            self.forces_ms,
            self.energy_ms,
            self.assembly_ms,
            self.factorization_ms,
            self.solve_ms,
            self.projection_ms,
            self.total_ms()
        )
    }
}

/// Milliseconds since `t`.
pub(crate) fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_of_running_totals_add_back_up() {
        let a = PhaseTimes {
            forces_ms: 1.0,
            energy_ms: 2.0,
            assembly_ms: 3.0,
            factorization_ms: 4.0,
            solve_ms: 5.0,
            projection_ms: 6.0,
        };
        let mut b = a;
        b += PhaseTimes {
            forces_ms: 0.5,
            solve_ms: 0.25,
            ..Default::default()
        };
        let d = b - a;
        assert_eq!(d.forces_ms, 0.5);
        assert_eq!(d.solve_ms, 0.25);
        assert_eq!(d.total_ms(), 0.75);
        assert_eq!(a.total_ms(), 21.0);
        assert!(a.to_string().contains("factorisation 4.0"), "{a}");
    }
}
