//! A shell's state as a frame (shared by the stepping and the static runs).

use crate::output::{Body, Field, Frame};
use anyhow::Result;
use balloon::shell::{ShellMaterial, ShellSimulation};

/// The current state as a frame with its fields: velocity, speed, pressure force (Eq. 15),
/// thickness, stretch and max_stretch against the rest shape.
pub fn shell_frame<M: ShellMaterial>(sim: &ShellSimulation<M>, step: usize) -> Result<Frame> {
    let x = sim.positions();
    let tris = sim.triangles();
    let force = balloon::fields::pressure_forces(x, tris, sim.gauge_pressure())?;
    let mut f = Frame::new(step, sim.time(), x.to_vec(), tris.to_vec())
        .with_velocity(sim.velocities().to_vec())?
        .with_stretch(sim.rest_positions())?
        .with_bodies(vec![
            Body::whole("balloon", x.len() / 3, tris.len()).with_pressure(sim.gauge_pressure()),
        ]);
    f.point_data.push(Field::vector("pressure_force", force));
    f.cell_data
        .push(Field::scalar("thickness", sim.thickness().to_vec()));
    Ok(f)
}
