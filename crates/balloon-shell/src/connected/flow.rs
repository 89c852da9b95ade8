//! The gas flow of connected balloons through their tubes at fixed volumes: backward Euler on
//! the finite tubes, `(I + dt L D) n' = n` (`L` the tubes' weighted graph Laplacian,
//! `D = diag(1/V_i)`), and the sharing out of the gas of balloons joined by instant tubes.

use nalgebra::{DMatrix, DVector};

use super::{Conductance, Tube};

/// The group representative of balloon `i` (union-find with path halving).
pub(crate) fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Backward Euler on the finite tubes at fixed volumes: `(I + dt L D) n' = n`.
pub(crate) fn finite_flow(tubes: &[Tube], dt: f64, volumes: &[f64], amounts: &[f64]) -> Vec<f64> {
    let n = amounts.len();
    let mut a = DMatrix::<f64>::identity(n, n);
    let mut any = false;
    for t in tubes {
        if let Conductance::Finite(kappa) = t.conductance {
            any = true;
            let c = dt * kappa;
            // Row i: + c (n_i / V_i - n_j / V_j); row j the opposite.
            a[(t.a, t.a)] += c / volumes[t.a];
            a[(t.a, t.b)] -= c / volumes[t.b];
            a[(t.b, t.b)] += c / volumes[t.b];
            a[(t.b, t.a)] -= c / volumes[t.a];
        }
    }
    if !any {
        return amounts.to_vec();
    }
    // A column-diagonally dominant M-matrix: LU with partial pivoting always succeeds.
    a.lu()
        .solve(&DVector::from_column_slice(amounts))
        .map_or_else(|| vec![f64::NAN; n], |x| x.as_slice().to_vec())
}

/// Shares the gas of every group of balloons joined by instant tubes (`groups`: each balloon's
/// group representative) at one pressure.
pub(crate) fn equalise_instant_groups(groups: &[usize], volumes: &[f64], amounts: &mut [f64]) {
    let n = amounts.len();
    for root in 0..n {
        let members: Vec<usize> = (0..n).filter(|&i| groups[i] == root).collect();
        if members.len() < 2 {
            continue;
        }
        let total: f64 = members.iter().map(|&i| amounts[i]).sum();
        let volume: f64 = members.iter().map(|&i| volumes[i]).sum();
        for &i in &members {
            amounts[i] = total * volumes[i] / volume;
        }
    }
}
