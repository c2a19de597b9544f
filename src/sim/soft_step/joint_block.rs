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
use std::ops::Range;

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

/// A row's Jacobian along its axis, per end (body 1, body 2): the angular part `r x axis`, the
/// angular response `I^-1 (r x axis)` to a unit impulse, and the inverse mass. Computed once
/// per solve, so each entry of `K` is a few dot products.
#[derive(Debug, Clone, Copy, Default)]
struct Jacobian {
    angular: [DVec3; 2],
    response: [DVec3; 2],
    inverse_mass: [f64; 2],
}

/// One connected group: its records, and the pairs of them that share a body (the only
/// off-diagonal entries of its `K`; a chain's are its neighbours).
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    pub records: Range<usize>,
    couplings: Range<usize>,
}

/// The records of the world's constraints, grouped by connected bodies, and the buffers one
/// group's solve works in (kept between steps).
#[derive(Debug, Clone, Default)]
pub struct JointBlocks {
    pub records: Vec<DistanceRecord>,
    pub groups: Vec<Group>,
    /// Pairs (i < j) of records of one group that share a body, by index within the group.
    couplings: Vec<(usize, usize)>,
    scratch: Scratch,
}

/// One group's system: geometry, rates and their ranges, `K`, impulses, the active set.
#[derive(Debug, Clone, Default)]
struct Scratch {
    geometries: Vec<Geometry>,
    jacobians: Vec<Jacobian>,
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
        let records: Vec<DistanceRecord> = keyed.iter().map(|(_, r)| *r).collect();
        let (mut groups, mut couplings) = (Vec::new(), Vec::new());
        let mut start = 0;
        for k in 1..=keyed.len() {
            if k == keyed.len() || keyed[k].0 != keyed[start].0 {
                let first = couplings.len();
                if k - start <= MAX_BLOCK {
                    couplings.extend(sharing_pairs(&records[start..k]));
                }
                groups.push(Group {
                    records: start..k,
                    couplings: first..couplings.len(),
                });
                start = k;
            }
        }
        Self {
            records,
            groups,
            couplings,
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

/// The pairs (i < j) of `records` that share a body.
fn sharing_pairs(records: &[DistanceRecord]) -> impl Iterator<Item = (usize, usize)> + '_ {
    let shares = |a: &DistanceRecord, b: &DistanceRecord| {
        [a.body1, a.body2]
            .iter()
            .any(|x| *x == b.body1 || *x == b.body2)
    };
    (0..records.len()).flat_map(move |i| {
        (i + 1..records.len())
            .filter(move |&j| shares(&records[i], &records[j]))
            .map(move |j| (i, j))
    })
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

/// The row's Jacobian at geometry `g`; `inverse(b)` is body b's inverse mass and world inverse
/// inertia.
fn jacobian(
    r: &DistanceRecord,
    g: &Geometry,
    inverse: &impl Fn(usize) -> (f64, DMat3),
) -> Jacobian {
    let mut out = Jacobian::default();
    for (end, (body, arm)) in [(r.body1, g.r1), (r.body2, g.r2)].into_iter().enumerate() {
        let (inverse_mass, inverse_inertia) = inverse(body);
        out.angular[end] = arm.cross(g.axis);
        out.response[end] = inverse_inertia * out.angular[end];
        out.inverse_mass[end] = inverse_mass;
    }
    out
}

/// `K_ij`: how a unit impulse of row j changes row i's rate, through the bodies they share
/// (body 1 is pushed against the axis, body 2 along it).
fn coupling(
    (ri, gi, ji): (&DistanceRecord, &Geometry, &Jacobian),
    (rj, gj, jj): (&DistanceRecord, &Geometry, &Jacobian),
) -> f64 {
    let mut k = 0.0;
    for (ei, bi) in [ri.body1, ri.body2].into_iter().enumerate() {
        for (ej, bj) in [rj.body1, rj.body2].into_iter().enumerate() {
            if bi != bj {
                continue;
            }
            let sign = if ei == ej { 1.0 } else { -1.0 };
            k += sign
                * (ji.inverse_mass[ei] * gi.axis.dot(gj.axis)
                    + ji.angular[ei].dot(jj.response[ej]));
        }
    }
    k
}

/// Solves `K_AA x = rhs_A` for the active rows (Cholesky, in place); false if not positive
/// definite. Only each row's envelope is visited (from its first non-zero entry to the
/// diagonal), where the factor's non-zeros stay (George and Liu, "Computer Solution of Large
/// Sparse Positive Definite Systems", 1981): a chain in link order is tridiagonal, so the
/// factorisation and both substitutions take time linear in its length.
fn cholesky_solve(k: &mut [f64], n: usize, x: &mut [f64]) -> bool {
    debug_assert!(n <= MAX_BLOCK);
    let mut first = [0usize; MAX_BLOCK];
    let mut inverse_diagonal = [0.0f64; MAX_BLOCK];
    for i in 0..n {
        first[i] = (0..i).find(|&p| k[i * n + p] != 0.0).unwrap_or(i);
    }
    for j in 0..n {
        let row_j = j * n;
        let mut d = k[row_j + j];
        for p in first[j]..j {
            d -= k[row_j + p] * k[row_j + p];
        }
        if d <= 1e-300 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        k[row_j + j] = d;
        inverse_diagonal[j] = 1.0 / d;
        for i in (j + 1..n).filter(|&i| first[i] <= j) {
            let row_i = i * n;
            let mut s = k[row_i + j];
            for p in first[i].max(first[j])..j {
                s -= k[row_i + p] * k[row_j + p];
            }
            k[row_i + j] = s * inverse_diagonal[j];
        }
    }
    // L y = b by rows, then L^T x = y by columns of L^T (rows of L): both within the envelope.
    for i in 0..n {
        let mut s = x[i];
        for p in first[i]..i {
            s -= k[i * n + p] * x[p];
        }
        x[i] = s * inverse_diagonal[i];
    }
    for i in (0..n).rev() {
        x[i] *= inverse_diagonal[i];
        let xi = x[i];
        for p in first[i]..i {
            x[p] -= k[i * n + p] * xi;
        }
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
        if n == 1 {
            return solve_one_range(u[0], lo[0], hi[0], k[0], &mut lambda[0]);
        }
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

/// [`Scratch::solve_ranges`] for a single row (a pendulum, a rod to a fixed body): the rate
/// `u` brought to the nearer end of `[lo, hi]` through `k`, or left alone inside it.
fn solve_one_range(u: f64, lo: f64, hi: f64, k: f64, lambda: &mut f64) -> bool {
    let target = if u < lo {
        lo
    } else if u > hi {
        hi
    } else {
        *lambda = 0.0;
        return true;
    };
    if k <= 1e-300 || !k.is_finite() {
        return false;
    }
    *lambda = (target - u) / k;
    true
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
        for g in &self.groups {
            if g.records.len() > MAX_BLOCK {
                for r in &self.records[g.records.clone()] {
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
        self.for_each_group(|scratch, group| {
            // SAFETY: groups share no moving body; poses are only read.
            unsafe { scratch.solve_group_velocities(group, poses, &bodies, inv_h, use_bias) };
            false
        });
    }

    /// Positions: each group's violated rows are moved back onto their bounds, through the
    /// bodies' masses, as an impulse would move them in unit time (velocities untouched).
    /// Returns whether any pose moved.
    pub fn project_positions(&mut self, poses: &mut [RigidBody], bodies: &[SolverBody]) -> bool {
        let poses = Shared::new(poses);
        self.for_each_group(|scratch, group| {
            // SAFETY: groups share no moving body, and only moving bodies' poses are written.
            unsafe { scratch.project_group(group, &poses, bodies) }
        })
    }

    /// Runs `f` on each group solved directly, with a scratch of its own: on the calling thread
    /// for a few groups, else on all threads (groups share no moving body, so the result is
    /// the same). True if `f` returned true for any group.
    fn for_each_group(&mut self, f: impl Fn(&mut Scratch, GroupView) -> bool + Sync) -> bool {
        const PARALLEL_GROUPS: usize = 64;
        let JointBlocks {
            records,
            groups,
            couplings,
            scratch,
        } = self;
        let view = |g: &Group| GroupView {
            records: &records[g.records.clone()],
            couplings: &couplings[g.couplings.clone()],
        };
        let direct = |g: &&Group| g.records.len() <= MAX_BLOCK;
        if groups.len() < PARALLEL_GROUPS {
            let mut any = false;
            for g in groups.iter().filter(direct) {
                any |= f(scratch, view(g));
            }
            return any;
        }
        groups
            .par_iter()
            .with_min_len(16)
            .filter(direct)
            .map_init(Scratch::default, |scratch, g| f(scratch, view(g)))
            .reduce(|| false, |a, b| a || b)
    }
}

/// One group's records and the pairs of them that share a body.
#[derive(Clone, Copy)]
struct GroupView<'a> {
    records: &'a [DistanceRecord],
    couplings: &'a [(usize, usize)],
}

impl Scratch {
    /// [`JointBlocks::solve_velocities`] for one group.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn solve_group_velocities(
        &mut self,
        group: GroupView,
        poses: &[RigidBody],
        bodies: &Shared<SolverBody>,
        inv_h: f64,
        use_bias: bool,
    ) {
        let records = group.records;
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
        self.fill_matrix(group, &inverse);
        if self.solve_ranges(n) {
            // SAFETY: as above.
            unsafe { self.apply(records, bodies) };
        }
    }

    /// [`JointBlocks::project_positions`] for one group; true if a pose moved.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn project_group(
        &mut self,
        group: GroupView,
        poses: &Shared<RigidBody>,
        bodies: &[SolverBody],
    ) -> bool {
        let records = group.records;
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
        self.fill_matrix(group, &inverse);
        if !self.solve_ranges(n) {
            return false;
        }
        // SAFETY: as above.
        unsafe { self.shift(records, poses) };
        true
    }

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

    /// The rows' Jacobians, then `K = J M^-1 J^T`: the diagonal and the entries of the records
    /// that share a body (the others are zero).
    fn fill_matrix(&mut self, group: GroupView, inverse: &impl Fn(usize) -> (f64, DMat3)) {
        let (records, geometries) = (group.records, &self.geometries);
        self.jacobians.clear();
        let rows = records.iter().zip(geometries);
        self.jacobians
            .extend(rows.map(|(r, g)| jacobian(r, g, inverse)));
        let n = records.len();
        let row = |i: usize| (&records[i], &geometries[i], &self.jacobians[i]);
        for i in 0..n {
            self.k[i * n + i] = coupling(row(i), row(i));
        }
        for &(i, j) in group.couplings {
            let v = coupling(row(i), row(j));
            self.k[i * n + j] = v;
            self.k[j * n + i] = v;
        }
    }

    /// Calls `f` for each end of each row with an impulse: the body, the change of its linear
    /// and its angular velocity that the impulse `lambda` makes (the change of position and
    /// the rotation it would make in unit time), and the body's inverse mass.
    fn for_each_move(
        &self,
        records: &[DistanceRecord],
        mut f: impl FnMut(usize, DVec3, DVec3, f64),
    ) {
        let rows = records.iter().zip(&self.geometries).zip(&self.jacobians);
        for (((r, g), jac), &l) in rows.zip(&self.lambda) {
            if l == 0.0 {
                continue;
            }
            for (end, (index, sign)) in [(r.body1, -1.0), (r.body2, 1.0)].into_iter().enumerate() {
                let m = jac.inverse_mass[end];
                f(
                    index,
                    (sign * l * m) * g.axis,
                    (sign * l) * jac.response[end],
                    m,
                );
            }
        }
    }

    /// The impulses `lambda` along the rows, on the group's moving bodies (the others, shared
    /// with other groups, are left alone: an impulse does not move them).
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn apply(&self, records: &[DistanceRecord], bodies: &Shared<SolverBody>) {
        self.for_each_move(records, |index, linear, angular, _| {
            // SAFETY: read, then written only if it moves: the caller's contract.
            if unsafe { bodies.get(index) }.is_static() {
                return;
            }
            let b = unsafe { bodies.get_mut(index) };
            b.linear_velocity += linear;
            b.angular_velocity += angular;
        });
    }

    /// The position change the impulses `lambda` would make in unit time, on the group's
    /// moving bodies.
    ///
    /// # Safety
    /// No other thread touches the group's moving bodies meanwhile.
    unsafe fn shift(&self, records: &[DistanceRecord], poses: &Shared<RigidBody>) {
        self.for_each_move(records, |index, shift, turn, inverse_mass| {
            if inverse_mass == 0.0 {
                return;
            }
            // SAFETY: a body with mass to move belongs to this group only.
            let pose = unsafe { poses.get_mut(index) };
            pose.position += shift;
            pose.orientation = crate::sim::integrate::rotate_by(pose.orientation, turn, 1.0);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;

    /// `x` with `a x = b` by Gaussian elimination with partial pivoting (an independent solve).
    fn eliminate(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Vec<f64> {
        for c in 0..n {
            let pivot = (c..n)
                .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
                .unwrap();
            for k in 0..n {
                a.swap(c * n + k, pivot * n + k);
            }
            b.swap(c, pivot);
            for r in c + 1..n {
                let f = a[r * n + c] / a[c * n + c];
                for k in c..n {
                    a[r * n + k] -= f * a[c * n + k];
                }
                b[r] -= f * b[c];
            }
        }
        let mut x = vec![0.0; n];
        for r in (0..n).rev() {
            let s: f64 = (r + 1..n).map(|k| a[r * n + k] * x[k]).sum();
            x[r] = (b[r] - s) / a[r * n + r];
        }
        x
    }

    /// Symmetric positive definite matrices with the sparsity of a chain, of a branching tree in
    /// a scrambled order (rows whose envelopes are ragged) and dense ones: the envelope
    /// factorisation solves them as elimination does.
    #[test]
    fn envelope_cholesky_solves_sparse_and_dense_systems() {
        let mut rng = Rng::new(7);
        for (case, n) in [(0, 9), (1, 12), (2, 7), (1, MAX_BLOCK)] {
            // Edges of a graph on the rows; K = D + sum over edges of a coupling (diagonally
            // dominant, hence positive definite).
            let edges: Vec<(usize, usize)> = match case {
                0 => (1..n).map(|i| (i - 1, i)).collect(),
                1 => (1..n)
                    .map(|i| ((i * 7) % n, (i * 7 + (i % 3) + 1) % n))
                    .collect(),
                _ => (0..n)
                    .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                    .collect(),
            };
            let mut k = vec![0.0; n * n];
            for &(i, j) in edges.iter().filter(|(i, j)| i != j) {
                let v = rng.range(-1.0, 1.0);
                k[i * n + j] += v;
                k[j * n + i] += v;
            }
            for i in 0..n {
                let off: f64 = (0..n).filter(|&j| j != i).map(|j| k[i * n + j].abs()).sum();
                k[i * n + i] = off + rng.range(0.1, 2.0);
            }
            let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            let expected = eliminate(k.clone(), b.clone(), n);
            let mut x = b.clone();
            assert!(cholesky_solve(&mut k.clone(), n, &mut x), "case {case}");
            for (got, want) in x.iter().zip(&expected) {
                assert!(
                    (got - want).abs() < 1e-10 * (1.0 + want.abs()),
                    "case {case}"
                );
            }
        }
        // Not positive definite: refused.
        let mut k = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_solve(&mut k, 2, &mut [1.0, 1.0]));
    }
}
