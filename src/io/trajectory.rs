//! Trajectory CSV: one row per body per step with time, centre of mass and orientation.

use crate::sim::World;
use std::io::Write;

pub const HEADER: &str = "step,time,body,x,y,z,qw,qx,qy,qz";

pub fn write_header(out: &mut (impl Write + ?Sized)) -> std::io::Result<()> {
    writeln!(out, "{HEADER}")
}

/// The rows of every body at the world's current step.
pub fn write_rows(out: &mut (impl Write + ?Sized), world: &World) -> std::io::Result<()> {
    for (i, b) in world.bodies.iter().enumerate() {
        let (p, q) = (b.position, b.orientation);
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{}",
            world.step_count, world.time, i, p.x, p.y, p.z, q.w, q.x, q.y, q.z
        )?;
    }
    Ok(())
}
