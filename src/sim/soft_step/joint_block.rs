//! Distance constraints solved exactly, a connected group (a chain, a pendulum) at a time: the
//! rows whose bound is reached or about to be form a small symmetric positive definite system
//! `K lambda = b` with `K = J M^-1 J^T`, solved directly (Cholesky) under the rows' sign limits by
//! an active-set loop; positions are then projected the same way (non-linear Gauss-Seidel with
//! an exact block). Gauss-Seidel would need about as many sweeps as a chain has links to pass a
//! load from its end to its anchor (the coursework needs hundreds of visits per step); a
//! direct solve passes it in one. Groups larger than [`MAX_BLOCK`] rows fall back to
//! Gauss-Seidel ([`super::joint_solver`]).

use super::constraint_graph::Shared;
use super::solver_body::SolverBody;
use crate::sim::body::RigidBody;
use crate::sim::constraint::DistanceConstraint;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Largest group solved directly (rows of one connected group of bodies).
pub const MAX_BLOCK: usize = 48;
/// Active-set rounds per solve (each drops or adds the rows that broke their limits).
const ACTIVE_SET_ROUNDS: usize = 8;

/// One constraint record: the distance between two body points kept within
/// `[lower, upper]` (equal bounds: a rigid rod).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistanceRecord {
    /// The first of the world's inequality constraints this record stands for, and how many
    /// (one, or a lower and an upper).
    pub first_constraint: usize,
    pub constraint_count: usize,
    pub body1: usize,
    pub body2: usize,
    pub local1: DVec3,
    pub local2: DVec3,
    pub lower: f64,
    pub upper: f64,
}

/// Which side of its range a row is held on in one solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Side {
    #[default]
    Free,
    Lower,
    Upper,
    /// Equal bounds: held from both sides.
    Both,
}

/// A record's geometry at the current poses.
#[derive(Debug, Clone, Copy, Default)]
struct Geometry {
    r1: DVec3,
    r2: DVec3,
    /// Unit vector from point 1 to point 2.
    axis: DVec3,
    length: f64,
}

/// The records of the world's constraints, grouped by connected bodies, and the buffers one
/// group's solve works in (kept between steps).
#[derive(Debug, Clone, Default)]
pub struct JointBlocks {
    pub records: Vec<DistanceRecord>,
    /// `records[start..end]` of each group.
    pub groups: Vec<(usize, usize)>,
    scratch: Scratch,
}

/// One group's system: geometry, rates and their ranges, `K`, impulses, the active set.
#[derive(Debug, Clone, Default)]
struct Scratch {
    geometries: Vec<Geometry>,
    u: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    lambda: Vec<f64>,
    k: Vec<f64>,
    side: Vec<Side>,
    active: Vec<usize>,
    sub: Vec<f64>,
    x: Vec<f64>,
}

impl JointBlocks {
    /// Pairs each record's lower and upper inequality (as the loader builds them) into one
    /// record and groups records that share a movable body (union-find).
    pub fn new(constraints: &[DistanceConstraint], bodies: &[RigidBody]) -> Self {
        let records = records_of(constraints);
        let mut parent: Vec<usize> = (0..bodies.len()).collect();
        let find = |parent: &mut Vec<usize>, mut x: usize| {
            while parent[x] != x {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            x
        };
        for r in &records {
            if bodies[r.body1].is_dynamic() && bodies[r.body2].is_dynamic() {
                let (a, b) = (find(&mut parent, r.body1), find(&mut parent, r.body2));
                parent[a.max(b)] = a.min(b);
            }
        }
        let mut keyed: Vec<(usize, DistanceRecord)> = records
            .into_iter()
            .filter(|r| bodies[r.body1].is_dynamic() || bodies[r.body2].is_dynamic())
            .map(|r| {
                let anchor = if bodies[r.body1].is_dynamic() {
                    r.body1
                } else {
                    r.body2
                };
                (find(&mut parent, anchor), r)
            })
            .collect();
        keyed.sort_by_key(|(group, _)| *group);
        let mut groups = Vec::new();
        let mut start = 0;
        for k in 1..=keyed.len() {
            if k == keyed.len() || keyed[k].0 != keyed[start].0 {
                groups.push((start, k));
                start = k;
            }
        }
        Self {
            records: keyed.into_iter().map(|(_, r)| r).collect(),
            groups,
            scratch: Scratch::default(),
        }
    }

    /// Whether the grouping still fits these constraints and bodies (same count of records;
    /// which bodies move decides the groups).
    pub fn fits(&self, constraints: &[DistanceConstraint], bodies: &[RigidBody]) -> bool {
        let count: usize = self.records.iter().map(|r| r.constraint_count).sum();
        count == constraints.len()
            && self
                .records
                .iter()
                .all(|r| bodies[r.body1].is_dynamic() || bodies[r.body2].is_dynamic())
    }
}

/// Consecutive lower and upper inequalities on the same points become one record.
fn records_of(constraints: &[DistanceConstraint]) -> Vec<DistanceRecord> {
    let mut out = Vec::with_capacity(constraints.len() / 2 + 1);
    let mut k = 0;
    while k < constraints.len() {
        let c = &constraints[k];
        let mut record = DistanceRecord {
            first_constraint: k,
            constraint_count: 1,
            body1: c.body1,
            body2: c.body2,
            local1: c.local1,
            local2: c.local2,
            lower: if c.is_upper { 0.0 } else { c.reference },
            upper: if c.is_upper {
                c.reference
            } else {
                f64::INFINITY
            },
        };
        if let Some(next) = constraints.get(k + 1)
            && (next.body1, next.body2, next.local1, next.local2)
                == (c.body1, c.body2, c.local1, c.local2)
            && next.is_upper != c.is_upper
        {
            if next.is_upper {
                record.upper = next.reference;
            } else {
                record.lower = next.reference;
            }
            record.constraint_count = 2;
            k += 1;
        }
        out.push(record);
        k += 1;
    }
    out
}

fn geometry(r: &DistanceRecord, a: &RigidBody, b: &RigidBody) -> Option<Geometry> {
    let r1 = a.orientation * r.local1;
    let r2 = b.orientation * r.local2;
    let d = (b.position + r2) - (a.position + r1);
    let length = d.length();
    (length > 1e-12 && length.is_finite()).then(|| Geometry {
        r1,
        r2,
        axis: d / length,
        length,
    })
}

/// `K_ij`: how a unit impulse of row j changes row i's rate (shared bodies only); `inverse(b)`
/// is body b's inverse mass and world inverse inertia.
fn coupling(
    ri: &DistanceRecord,
    gi: &Geometry,
    rj: &DistanceRecord,
    gj: &Geometry,
    inverse: &impl Fn(usize) -> (f64, DMat3),
) -> f64 {
    let mut k = 0.0;
    for (bi, si, ai) in [(ri.body1, -1.0, gi.r1), (ri.body2, 1.0, gi.r2)] {
        for (bj, sj, aj) in [(rj.body1, -1.0, gj.r1), (rj.body2, 1.0, gj.r2)] {
            if bi != bj {
                continue;
            }
            let (inverse_mass, inverse_inertia) = inverse(bi);
            let (ui, uj) = (ai.cross(gi.axis), aj.cross(gj.axis));
            k += si * sj * (inverse_mass * gi.axis.dot(gj.axis) + ui.dot(inverse_inertia * uj));
        }
    }
    k
}

/// Solves `K_AA x = rhs_A` for the active rows (Cholesky, in place); false if not positive
/// definite.
fn cholesky_solve(k: &mut [f64], n: usize, x: &mut [f64]) -> bool {
    for j in 0..n {
        let mut d = k[j * n + j];
        for p in 0..j {
            d -= k[j * n + p] * k[j * n + p];
        }
        if d <= 1e-300 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        k[j * n + j] = d;
        for i in j + 1..n {
            let mut s = k[i * n + j];
            for p in 0..j {
                s -= k[i * n + p] * k[j * n + p];
            }
            k[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = x[i];
        for p in 0..i {
            s -= k[i * n + p] * x[p];
        }
        x[i] = s / k[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for p in i + 1..n {
            s -= k[p * n + i] * x[p];
        }
        x[i] = s / k[i * n + i];
    }
    true
}

impl Scratch {
    fn reset(&mut self, n: usize) {
        for v in [&mut self.u, &mut self.lo, &mut self.hi, &mut self.lambda] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.k.clear();
        self.k.resize(n * n, 0.0);
    }

    /// The rows' rates `u` must end within `[lo, hi]` (per row); finds impulses `lambda` with
    /// `u + K lambda` in range, `lambda >= 0` where held at its low end, `<= 0` at its high
    /// end. False when the block could not be solved (the caller leaves the group alone).
    fn solve_ranges(&mut self, n: usize) -> bool {
        let Scratch {
            u,
            lo,
            hi,
            lambda,
            k,
            side,
            active,
            sub,
            x,
            ..
        } = self;
        side.clear();
        side.extend((0..n).map(|i| {
            if lo[i] == hi[i] {
                Side::Both
            } else if u[i] < lo[i] {
                Side::Lower
            } else if u[i] > hi[i] {
                Side::Upper
            } else {
                Side::Free
            }
        }));
        for _ in 0..ACTIVE_SET_ROUNDS {
            active.clear();
            active.extend((0..n).filter(|&i| side[i] != Side::Free));
            let m = active.len();
            sub.clear();
            sub.resize(m * m, 0.0);
            x.clear();
            for (a, &i) in active.iter().enumerate() {
                for (b, &j) in active.iter().enumerate() {
                    sub[a * m + b] = k[i * n + j];
                }
                x.push(if side[i] == Side::Upper { hi[i] } else { lo[i] } - u[i]);
            }
            if !cholesky_solve(sub, m, x) {
                return false;
            }
            lambda.iter_mut().for_each(|l| *l = 0.0);
            for (a, &i) in active.iter().enumerate() {
                lambda[i] = x[a];
            }
            if !update_sides(n, u, lo, hi, lambda, k, side) {
                return true;
            }
        }
        true
    }
}

/// Rows pushing the wrong way let go; rows now out of range are held. True if any changed.
fn update_sides(
    n: usize,
    u: &[f64],
    lo: &[f64],
    hi: &[f64],
    lambda: &[f64],
    k: &[f64],
    side: &mut [Side],
) -> bool {
    let mut changed = false;
    for i in 0..n {
        let wrong = match side[i] {
            Side::Lower => lambda[i] < 0.0,
            Side::Upper => lambda[i] > 0.0,
            _ => false,
        };
        if wrong {
            side[i] = Side::Free;
            changed = true;
        }
    }
    if changed {
        return true;
    }
    for i in 0..n {
        if side[i] != Side::Free {
            continue;
        }
        let rate = u[i] + (0..n).map(|j| k[i * n + j] * lambda[j]).sum::<f64>();
        let tolerance = 1e-12 * (1.0 + rate.abs());
        if rate < lo[i] - tolerance {
            side[i] = Side::Lower;
            changed = true;
        } else if rate > hi[i] + tolerance {
            side[i] = Side::Upper;
            changed = true;
        }
    }
    changed
}

impl JointBlocks {
    /// The world's constraints (indices) in groups too large to solve directly.
    pub fn large_group_constraints(&self) -> Vec<usize> {
        let mut out = Vec::new();
        for &(start, end) in &self.groups {
            if end - start > MAX_BLOCK {
                for r in &self.records[start..end] {
                    out.extend(r.first_constraint..r.first_constraint + r.constraint_count);
                }
            }
        }
        out.sort_unstable();
        out
    }

    /// Velocities: each group's rows end the pass with rates in range. With `use_bias` a
    /// violated bound is approached back at its full error per substep, without it only not
    /// crossed; a bound not yet reached may be reached but not passed (speculative).
    pub fn solve_velocities(
        &mut self,
        poses: &[RigidBody],
        bodies: &mut [SolverBody],
        inv_h: f64,
        use_bias: bool,
    ) {
        let bodies = Shared::new(bodies);
        self.for_each_group(|scratch, records| {
            // SAFETY: groups share no moving body; poses are only read.
            unsafe { scratch.solve_group_velocities(records, poses, &bodies, inv_h, use_bias) };
            false
        });
    }

    /// Positions: each group's violated rows are moved back onto their bounds, through the
    /// bodies' masses, as an impulse would move them in unit time (velocities untouched).
    /// Returns whether any pose moved.
    pub fn project_positions(&mut self, poses: &mut [RigidBody], bodies: &[SolverBody]) -> bool {
        let poses = Shared::new(poses);
        self.for_each_group(|scratch, records| {
            // SAFETY: groups share no moving body, and only moving bodies' poses are written.
            unsafe { scratch.project_group(records, &poses, bodies) }
        })
    }

    /// Runs `f` on each group solved directly, with a scratch of its own: on the calling thread
    /// for a few groups, else on all threads (groups share no moving body, so the result is
    /// the same). True if `f` returned true for any group.
    fn for_each_group(
        &mut self,
        f: impl Fn(&mut Scratch, &[DistanceRecord]) -> bool + Sync,
    ) -> bool {
        const PARALLEL_GROUPS: usize = 64;
        let JointBlocks {
            records,
            groups,
            scratch,
        } = self;
        let direct = |&(start, end): &(usize, usize)| end - start <= MAX_BLOCK;
        let records = &records[..];
        if groups.len() < PARALLEL_GROUPS {
            let mut any = false;
            for &(start, end) in groups.iter().filter(|g| direct(g)) {
                any |= f(scratch, &records[start..end]);
            }
            return any;
        }
        groups
            .par_iter()
            .with_min_len(16)
            .filter(|g| direct(g))
            .map_init(Scratch::default, |scratch, &(start, end)| {
                f(scratch, &records[start..end])
            })
            .reduce(|| false, |a, b| a || b)
    }
}

impl Scratch {
    /// [`JointBlocks::solve_velocities`] for one group.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn solve_group_velocities(
        &mut self,
        records: &[DistanceRecord],
        poses: &[RigidBody],
        bodies: &Shared<SolverBody>,
        inv_h: f64,
        use_bias: bool,
    ) {
        if !self.load_geometry(records, |i| &poses[i]) {
            return;
        }
        let n = records.len();
        self.reset(n);
        for (i, (r, g)) in records.iter().zip(&self.geometries).enumerate() {
            // SAFETY: the group's bodies (caller's contract).
            let (b1, b2) = unsafe { (bodies.get(r.body1), bodies.get(r.body2)) };
            self.u[i] = g
                .axis
                .dot(b2.point_velocity(g.r2) - b1.point_velocity(g.r1));
            let allowed = |gap: f64| {
                if gap > 0.0 || use_bias {
                    gap * inv_h
                } else {
                    0.0
                }
            };
            (self.lo[i], self.hi[i]) = if r.lower == r.upper {
                let rate = if use_bias {
                    (r.lower - g.length) * inv_h
                } else {
                    0.0
                };
                (rate, rate)
            } else {
                (-allowed(g.length - r.lower), allowed(r.upper - g.length))
            };
        }
        let inverse = |i: usize| {
            // SAFETY: as above.
            let b = unsafe { bodies.get(i) };
            (b.inverse_mass, b.inverse_inertia)
        };
        fill_matrix(&mut self.k, records, &self.geometries, &inverse);
        if self.solve_ranges(n) {
            // SAFETY: as above.
            unsafe { apply(records, &self.geometries, &self.lambda, bodies) };
        }
    }

    /// [`JointBlocks::project_positions`] for one group; true if a pose moved.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn project_group(
        &mut self,
        records: &[DistanceRecord],
        poses: &Shared<RigidBody>,
        bodies: &[SolverBody],
    ) -> bool {
        // SAFETY: the group's poses are written only by this call (caller's contract).
        if !self.load_geometry(records, |i| unsafe { poses.get(i) }) {
            return false;
        }
        let n = records.len();
        let inside = records
            .iter()
            .zip(&self.geometries)
            .all(|(r, g)| g.length >= r.lower && g.length <= r.upper);
        if inside {
            return false;
        }
        self.reset(n);
        for (i, (r, g)) in records.iter().zip(&self.geometries).enumerate() {
            (self.u[i], self.lo[i], self.hi[i]) = (g.length, r.lower, r.upper);
        }
        let inverse = |i: usize| (bodies[i].inverse_mass, bodies[i].inverse_inertia);
        fill_matrix(&mut self.k, records, &self.geometries, &inverse);
        if !self.solve_ranges(n) {
            return false;
        }
        // SAFETY: as above.
        unsafe { shift(records, &self.geometries, &self.lambda, poses, bodies) };
        true
    }
}

impl Scratch {
    /// Each record's geometry at the current poses (`pose(i)`: body i's); false if a record
    /// has none.
    fn load_geometry<'p>(
        &mut self,
        records: &[DistanceRecord],
        pose: impl Fn(usize) -> &'p RigidBody,
    ) -> bool {
        self.geometries.clear();
        for r in records {
            match geometry(r, pose(r.body1), pose(r.body2)) {
                Some(g) => self.geometries.push(g),
                None => return false,
            }
        }
        true
    }
}

fn fill_matrix(
    k: &mut [f64],
    records: &[DistanceRecord],
    geometries: &[Geometry],
    inverse: &impl Fn(usize) -> (f64, DMat3),
) {
    let n = records.len();
    for i in 0..n {
        for j in i..n {
            let v = coupling(
                &records[i],
                &geometries[i],
                &records[j],
                &geometries[j],
                inverse,
            );
            k[i * n + j] = v;
            k[j * n + i] = v;
        }
    }
}

/// The impulses `lambda` along the rows, on the group's moving bodies (the others, shared with
/// other groups, are left alone: an impulse does not move them).
///
/// # Safety
/// No other thread touches the group's moving bodies meanwhile.
unsafe fn apply(
    records: &[DistanceRecord],
    geometries: &[Geometry],
    lambda: &[f64],
    bodies: &Shared<SolverBody>,
) {
    for ((r, g), &l) in records.iter().zip(geometries).zip(lambda) {
        if l == 0.0 {
            continue;
        }
        let p = l * g.axis;
        for (index, arm, impulse) in [(r.body1, g.r1, -p), (r.body2, g.r2, p)] {
            // SAFETY: read, then written only if it moves: the caller's contract.
            if unsafe { bodies.get(index) }.is_static() {
                continue;
            }
            unsafe { bodies.get_mut(index) }.apply(arm, impulse);
        }
    }
}

/// The position change the impulses `lambda` would make in unit time, on the group's moving
/// bodies.
///
/// # Safety
/// No other thread touches the group's moving bodies meanwhile.
unsafe fn shift(
    records: &[DistanceRecord],
    geometries: &[Geometry],
    lambda: &[f64],
    poses: &Shared<RigidBody>,
    bodies: &[SolverBody],
) {
    for ((r, g), &l) in records.iter().zip(geometries).zip(lambda) {
        if l == 0.0 {
            continue;
        }
        let p = l * g.axis;
        for (index, arm, impulse) in [(r.body1, g.r1, -p), (r.body2, g.r2, p)] {
            let b = &bodies[index];
            if b.inverse_mass == 0.0 {
                continue;
            }
            // SAFETY: a body with mass to move belongs to this group only.
            let pose = unsafe { poses.get_mut(index) };
            pose.position += b.inverse_mass * impulse;
            let turn = b.inverse_inertia * arm.cross(impulse);
            pose.orientation = crate::sim::integrate::rotate_by(pose.orientation, turn, 1.0);
        }
    }
}
