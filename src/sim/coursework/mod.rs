//! The coursework's solver, reproduced: contacts resolved pair by pair by a linear projection
//! and one restitution impulse ([`contact`], [`contact_stage`]), distance constraints projected
//! on positions then velocities ([`projection`]) under a visit budget ([`schedule`]).

pub mod contact;
pub mod contact_stage;
pub mod projection;
pub mod schedule;
