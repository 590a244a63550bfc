//! One longitudinal MPC quadratic program, built once and updated every cycle.
//!
//! A vehicle moves along its own path as a double integrator in arc length: `s_{k+1} = s_k + dt v_k
//! + ½ dt² a_k`, `v_{k+1} = v_k + dt a_k`, over `N` steps. The cost tracks a reference speed (and
//! optionally a reference station), penalizes acceleration and its change, and carries one *event*:
//! a linear condition on the position at an arbitrary time `T` after now,
//!
//! - `Upper`: `s(T) ≤ station` (not yet there at `T`),
//! - `Lower`: `s(T) ≥ station` (already there at `T`),
//! - `Equal`: `s(T) = station` (there exactly at `T`),
//!
//! where `s(T)` interpolates linearly between steps and, beyond the horizon, extrapolates at the
//! terminal speed (`s_N + (T − N dt) v_N`): the event may lie past the horizon, which is what keeps
//! plans consistent from cycle to cycle when the conflict is still far. Because speed stays ≥ 0, one
//! such row is enough to order two vehicles through a zone. The event is softened by non-negative
//! slacks with an exact (linear) penalty, so the problem is always feasible and the slack says by
//! how much the event was missed.
//!
//! Variables `x = [s_1..s_N, v_1..v_N, a_0..a_{N−1}, σ⁺, σ⁻]`. The sparsity of `P` and `A` never
//! changes: the event row holds every `s_k` and `v_N` (most of them numerically zero), so each cycle
//! only `q`, `b` and the event row's values are written, and Clarabel re-solves without rebuilding
//! (presolve and structural-zero dropping off).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

/// How the event constrains the position at its time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventKind {
    /// `s(T) ≤ station`.
    Upper,
    /// `s(T) ≥ station`.
    Lower,
    /// `s(T) = station`.
    Equal,
}

/// Fixed parameters of one QP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QpShape {
    /// Steps.
    pub horizon: usize,
    /// Step, s.
    pub dt_s: f64,
    /// Weight on `(v − v_ref)²`.
    pub w_speed: f64,
    /// Weight on `a²`.
    pub w_accel: f64,
    /// Weight on `(a_k − a_{k−1} − (r_k − r_{k−1}))²`: the plan's jerk beyond its acceleration
    /// shape `r`'s own (`r` 0 unless [`LongitudinalQp::a_ref_mut`] sets it; for `k = 0` against
    /// the acceleration applied last, all of it).
    pub w_jerk: f64,
    /// Exact penalty per metre of event violation.
    pub w_slack: f64,
    /// The event's kind (fixed: it decides which cone its row is in).
    pub event: EventKind,
}

/// Share of the largest deceleration a plan may use to come down to a speed cap ahead.
pub const CAP_DECEL_SHARE: f64 = 0.8;

/// Per-cycle data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QpInput {
    /// Arc length now, m.
    pub s0_m: f64,
    /// Speed now, m/s.
    pub v0_mps: f64,
    /// Acceleration applied last, m/s².
    pub a_prev_mps2: f64,
    /// Speed limits, m/s.
    pub v_max_mps: f64,
    /// Largest acceleration, m/s².
    pub a_max_mps2: f64,
    /// Largest deceleration (positive), m/s².
    pub d_max_mps2: f64,
    /// Event time after now, s (`None`: no event).
    pub event_t_s: Option<f64>,
    /// Event station, m.
    pub event_station_m: f64,
}

/// Outcome of one solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QpStatus {
    /// Solved to tolerance.
    Solved,
    /// Solved to reduced tolerance.
    AlmostSolved,
    /// The solver stopped without a usable solution (iteration limit, numerical trouble).
    Failed,
}

/// Which variable a solution index holds.
fn idx_s(k: usize) -> usize {
    k - 1
}

/// Errors building a QP.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QpError {
    /// Horizon or step out of range.
    #[error("QP shape: {0}")]
    Shape(String),
    /// Clarabel refused the problem.
    #[error("QP setup: {0}")]
    Setup(String),
}

/// A longitudinal MPC QP with its persistent Clarabel solver.
pub struct LongitudinalQp {
    shape: QpShape,
    solver: DefaultSolver<f64>,
    p_mat: CscMatrix<f64>,
    a_mat: CscMatrix<f64>,
    q: Vec<f64>,
    b: Vec<f64>,
    /// Positions in `a_mat.nzval` of the event row's entries: `s_1..s_N`, then `v_N`.
    event_nz: Vec<usize>,
    /// Row index of the event.
    event_row: usize,
    n_eq: usize,
    /// References over the horizon (filled by the caller), `k = 1..N`.
    v_ref: Vec<f64>,
    /// Acceleration shape over the horizon (filled by the caller, 0 by default), `k = 0..N−1`.
    a_ref: Vec<f64>,
    v_cap: Vec<f64>,
    out_s: Vec<f64>,
    out_v: Vec<f64>,
    out_a: Vec<f64>,
    slack_m: f64,
    status: QpStatus,
    iterations: u32,
}

impl LongitudinalQp {
    /// Builds the problem and its solver once.
    pub fn new(shape: QpShape) -> Result<Self, QpError> {
        let n = shape.horizon;
        if !((2..=200).contains(&n) && shape.dt_s > 0.0 && shape.dt_s <= 1.0) {
            return Err(QpError::Shape(format!("horizon {n} (2..=200), dt {} s (0, 1]", shape.dt_s)));
        }
        let nv = 3 * n + 2;
        let (sp, sm) = (3 * n, 3 * n + 1);
        let iv = |k: usize| n + k - 1;
        let ia = |k: usize| 2 * n + k;
        let dt = shape.dt_s;

        // Cost (upper triangle, column-major triplets).
        let mut p_trip: Vec<(usize, usize, f64)> = Vec::new();
        for k in 1..=n {
            p_trip.push((iv(k), iv(k), 2.0 * shape.w_speed));
        }
        for k in 0..n {
            let mut diag = 2.0 * shape.w_accel + 2.0 * shape.w_jerk;
            if k + 1 < n {
                diag += 2.0 * shape.w_jerk;
            }
            p_trip.push((ia(k), ia(k), diag));
            if k >= 1 {
                p_trip.push((ia(k - 1), ia(k), -2.0 * shape.w_jerk));
            }
        }
        p_trip.push((sp, sp, 2e-6));
        p_trip.push((sm, sm, 2e-6));
        let p_mat = csc_from_triplets(nv, nv, &p_trip);

        // Constraints: equalities first (dynamics, [equal event]), then inequalities.
        let mut a_trip: Vec<(usize, usize, f64)> = Vec::new();
        let mut row = 0;
        for k in 0..n {
            // s_{k+1} − s_k − dt v_k − ½ dt² a_k = [s0 + dt v0 if k = 0]
            a_trip.push((row, idx_s(k + 1), 1.0));
            if k >= 1 {
                a_trip.push((row, idx_s(k), -1.0));
                a_trip.push((row, iv(k), -dt));
            }
            a_trip.push((row, ia(k), -0.5 * dt * dt));
            row += 1;
            // v_{k+1} − v_k − dt a_k = [v0 if k = 0]
            a_trip.push((row, iv(k + 1), 1.0));
            if k >= 1 {
                a_trip.push((row, iv(k), -1.0));
            }
            a_trip.push((row, ia(k), -dt));
            row += 1;
        }
        let mut event_row = usize::MAX;
        let push_event = |row: usize, a_trip: &mut Vec<(usize, usize, f64)>| {
            for k in 1..=n {
                a_trip.push((row, idx_s(k), 0.0));
            }
            a_trip.push((row, iv(n), 0.0));
            a_trip.push((row, sp, -1.0));
            a_trip.push((row, sm, if shape.event == EventKind::Equal { 1.0 } else { 0.0 }));
        };
        if shape.event == EventKind::Equal {
            event_row = row;
            push_event(row, &mut a_trip);
            row += 1;
        }
        let n_eq = row;
        for k in 0..n {
            a_trip.push((row, ia(k), 1.0));
            a_trip.push((row + 1, ia(k), -1.0));
            row += 2;
        }
        for k in 1..=n {
            a_trip.push((row, iv(k), 1.0));
            a_trip.push((row + 1, iv(k), -1.0));
            row += 2;
        }
        if shape.event != EventKind::Equal {
            event_row = row;
            push_event(row, &mut a_trip);
            row += 1;
        }
        a_trip.push((row, sp, -1.0));
        a_trip.push((row + 1, sm, -1.0));
        row += 2;
        let m = row;
        let a_mat = csc_from_triplets(m, nv, &a_trip);
        let event_nz: Vec<usize> = (1..=n)
            .map(idx_s)
            .chain(std::iter::once(iv(n)))
            .filter_map(|col| nz_index(&a_mat, event_row, col))
            .collect();
        if event_nz.len() != n + 1 {
            return Err(QpError::Setup("event row layout".into()));
        }
        let cones = [SupportedConeT::ZeroConeT(n_eq), SupportedConeT::NonnegativeConeT(m - n_eq)];
        let q = vec![0.0; nv];
        let b = vec![0.0; m];
        let settings: DefaultSettings<f64> = DefaultSettingsBuilder::default()
            .verbose(false)
            .presolve_enable(false)
            .input_sparse_dropzeros(false)
            .equilibrate_enable(true)
            // Centimetre-level plans need far less than Clarabel's default 1e-8 gap tolerance.
            .tol_gap_abs(1e-6)
            .tol_gap_rel(1e-6)
            .tol_feas(1e-7)
            .max_iter(60)
            .iterative_refinement_enable(false)
            .build()
            .map_err(|e| QpError::Setup(e.to_string()))?;
        let solver = DefaultSolver::new(&p_mat, &q, &a_mat, &b, &cones, settings)
            .map_err(|e| QpError::Setup(format!("{e:?}")))?;
        Ok(Self {
            shape,
            solver,
            p_mat,
            a_mat,
            q,
            b,
            event_nz,
            event_row,
            n_eq,
            v_ref: vec![0.0; n],
            a_ref: vec![0.0; n],
            v_cap: vec![f64::INFINITY; n],
            out_s: vec![0.0; n + 1],
            out_v: vec![0.0; n + 1],
            out_a: vec![0.0; n],
            slack_m: 0.0,
            status: QpStatus::Failed,
            iterations: 0,
        })
    }

    /// The fixed parameters.
    pub fn shape(&self) -> &QpShape {
        &self.shape
    }

    /// Speed caps for steps `1..=N` below `v_max` (curves ahead; `f64::INFINITY`: none). A plan
    /// comes down to a cap no harder than [`CAP_DECEL_SHARE`] of the largest deceleration, so the
    /// bound is always feasible (write before [`Self::solve`]).
    pub fn v_cap_mut(&mut self) -> &mut [f64] {
        &mut self.v_cap
    }

    /// Reference speeds for steps `1..=N` (write before [`Self::solve`]).
    pub fn v_ref_mut(&mut self) -> &mut [f64] {
        &mut self.v_ref
    }

    /// The reference speeds the last solve tracked.
    pub fn v_ref(&self) -> &[f64] {
        &self.v_ref
    }

    /// The acceleration shape for steps `0..N` (write before [`Self::solve`]; 0 unless set): the
    /// plan's jerk is counted beyond this shape's own, so a shape taken from a human's motion is
    /// kept (easing off and pressing on where it does) wherever the other terms allow, at
    /// whatever offset the event and the speed reference ask.
    pub fn a_ref_mut(&mut self) -> &mut [f64] {
        &mut self.a_ref
    }

    /// Solves for `input`; the plan is then in [`Self::station`], [`Self::speed`], [`Self::accel`].
    pub fn solve(&mut self, input: &QpInput) -> QpStatus {
        let n = self.shape.horizon;
        let dt = self.shape.dt_s;
        let sh = self.shape;
        // q: references and the previous acceleration.
        for (k, vr) in (1..=n).zip(&self.v_ref) {
            if let Some(q) = self.q.get_mut(n + k - 1) {
                *q = -2.0 * sh.w_speed * vr;
            }
        }
        // The shape's own jerk per step: none at k = 0 (the first step keeps to the acceleration
        // applied last), then a_ref,k − a_ref,k−1.
        let a_ref = &self.a_ref;
        let d = |k: usize| match (k.checked_sub(1).and_then(|j| a_ref.get(j)), a_ref.get(k)) {
            (Some(before), Some(now)) => now - before,
            _ => 0.0,
        };
        for k in 0..n {
            if let Some(q) = self.q.get_mut(2 * n + k) {
                let prev = if k == 0 { -2.0 * sh.w_jerk * input.a_prev_mps2 } else { 0.0 };
                *q = prev - 2.0 * sh.w_jerk * (d(k) - d(k + 1));
            }
        }
        if let Some(q) = self.q.get_mut(3 * n) {
            *q = sh.w_slack;
        }
        if let Some(q) = self.q.get_mut(3 * n + 1) {
            *q = sh.w_slack;
        }
        // b: dynamics from the initial state, bounds, event.
        self.b.iter_mut().for_each(|x| *x = 0.0);
        set(&mut self.b, 0, input.s0_m + dt * input.v0_mps);
        set(&mut self.b, 1, input.v0_mps);
        let mut row = self.n_eq;
        for _ in 0..n {
            set(&mut self.b, row, input.a_max_mps2);
            set(&mut self.b, row + 1, input.d_max_mps2);
            row += 2;
        }
        for k in 0..n {
            let ramp = input.v0_mps - CAP_DECEL_SHARE * input.d_max_mps2 * (k + 1) as f64 * dt;
            let cap = self.v_cap.get(k).copied().unwrap_or(f64::INFINITY);
            set(&mut self.b, row, input.v_max_mps.min(cap.max(ramp)));
            set(&mut self.b, row + 1, 0.0);
            row += 2;
        }
        self.write_event(input);
        // Clarabel keeps its own scaled copies: hand it the new data.
        let ok = self.solver.update_q(&self.q).is_ok()
            && self.solver.update_b(&self.b).is_ok()
            && self.solver.update_A(&self.a_mat).is_ok();
        if !ok {
            self.status = QpStatus::Failed;
            return self.status;
        }
        self.solver.solve();
        let sol = &self.solver.solution;
        self.iterations = sol.iterations;
        self.status = match sol.status {
            SolverStatus::Solved => QpStatus::Solved,
            SolverStatus::AlmostSolved => QpStatus::AlmostSolved,
            _ => QpStatus::Failed,
        };
        if self.status == QpStatus::Failed || sol.x.iter().any(|v| !v.is_finite()) {
            self.status = QpStatus::Failed;
            return self.status;
        }
        set(&mut self.out_s, 0, input.s0_m);
        set(&mut self.out_v, 0, input.v0_mps);
        for k in 1..=n {
            set(&mut self.out_s, k, sol.x.get(k - 1).copied().unwrap_or(0.0));
            set(&mut self.out_v, k, sol.x.get(n + k - 1).copied().unwrap_or(0.0));
        }
        for k in 0..n {
            set(&mut self.out_a, k, sol.x.get(2 * n + k).copied().unwrap_or(0.0));
        }
        self.slack_m =
            sol.x.get(3 * n).copied().unwrap_or(0.0).max(0.0) + sol.x.get(3 * n + 1).copied().unwrap_or(0.0).max(0.0);
        self.status
    }

    /// Writes the event row's coefficients and right-hand side.
    fn write_event(&mut self, input: &QpInput) {
        let n = self.shape.horizon;
        let dt = self.shape.dt_s;
        for &i in &self.event_nz {
            set(&mut self.a_mat.nzval, i, 0.0);
        }
        let Some(t) = input.event_t_s.filter(|t| t.is_finite()) else {
            // No event: 0 ≤ big (inequality) or 0 = 0 with free slacks (equality).
            let rhs = if self.shape.event == EventKind::Equal { 0.0 } else { 1e6 };
            set(&mut self.b, self.event_row, rhs);
            return;
        };
        let t = t.max(0.0);
        // s(T) = Σ c_k s_k + c_v v_N + c_0 s0.
        let mut c0 = 0.0;
        let horizon_t = n as f64 * dt;
        if t >= horizon_t {
            self.coef_s(n, 1.0);
            if let Some(&i) = self.event_nz.last() {
                set(&mut self.a_mat.nzval, i, t - horizon_t);
            }
        } else {
            let k = (t / dt).floor() as usize;
            let alpha = t / dt - k as f64;
            if k == 0 {
                c0 = 1.0 - alpha;
            } else {
                self.coef_s(k, 1.0 - alpha);
            }
            self.coef_s(k + 1, alpha);
        }
        let sign = if self.shape.event == EventKind::Lower { -1.0 } else { 1.0 };
        if sign < 0.0 {
            for &i in &self.event_nz {
                if let Some(v) = self.a_mat.nzval.get_mut(i) {
                    *v = -*v;
                }
            }
        }
        set(&mut self.b, self.event_row, sign * (input.event_station_m - c0 * input.s0_m));
    }

    fn coef_s(&mut self, k: usize, c: f64) {
        if let Some(&i) = self.event_nz.get(k - 1) {
            set(&mut self.a_mat.nzval, i, c);
        }
    }

    /// Planned stations `s_0..s_N`.
    pub fn station(&self) -> &[f64] {
        &self.out_s
    }

    /// Planned speeds `v_0..v_N`.
    pub fn speed(&self) -> &[f64] {
        &self.out_v
    }

    /// Planned accelerations `a_0..a_{N−1}`.
    pub fn accel(&self) -> &[f64] {
        &self.out_a
    }

    /// How far the event was missed, m.
    pub fn slack_m(&self) -> f64 {
        self.slack_m
    }

    /// Status of the last solve.
    pub fn status(&self) -> QpStatus {
        self.status
    }

    /// Interior-point iterations of the last solve.
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    /// Infinity norms of the KKT residuals of the last solution in the problem's own scaling:
    /// stationarity `‖P x + q + Aᵀ z‖`, primal feasibility `‖A x + s − b‖`, and complementarity
    /// `|sᵀ z|` relative to `1 + |objective|`. For tests and diagnostics (allocates).
    #[allow(clippy::indexing_slicing)] // indices come from the matrices' own CSC structure
    pub fn kkt_residuals(&self) -> (f64, f64, f64) {
        let sol = &self.solver.solution;
        let (x, z, sl) = (&sol.x, &sol.z, &sol.s);
        let mut grad = self.q.clone();
        // P is stored as its upper triangle.
        for col in 0..self.p_mat.n {
            let (a, b) = (self.p_mat.colptr[col], self.p_mat.colptr[col + 1]);
            for i in a..b {
                let (row, v) = (self.p_mat.rowval[i], self.p_mat.nzval[i]);
                grad[row] += v * x[col];
                if row != col {
                    grad[col] += v * x[row];
                }
            }
        }
        let mut ax = vec![0.0; self.a_mat.m];
        for col in 0..self.a_mat.n {
            for i in self.a_mat.colptr[col]..self.a_mat.colptr[col + 1] {
                let (row, v) = (self.a_mat.rowval[i], self.a_mat.nzval[i]);
                ax[row] += v * x[col];
                grad[col] += v * z[row];
            }
        }
        let stat = grad.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
        let primal = ax.iter().zip(sl).zip(&self.b).fold(0.0_f64, |m, ((a, s), b)| m.max((a + s - b).abs()));
        let comp = sl.iter().zip(z).map(|(s, z)| s * z).sum::<f64>().abs() / (1.0 + sol.obj_val.abs());
        (stat, primal, comp)
    }

    /// First time (after now) at which the plan reaches `station`, interpolated between steps and
    /// extrapolated at the terminal speed beyond the horizon. `None` if it never does.
    pub fn time_at_station(&self, station: f64) -> Option<f64> {
        time_at_station(&self.out_s, &self.out_v, self.shape.dt_s, station)
    }
}

impl std::fmt::Debug for LongitudinalQp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LongitudinalQp")
            .field("shape", &self.shape)
            .field("status", &self.status)
            .finish_non_exhaustive()
    }
}

/// See [`LongitudinalQp::time_at_station`].
pub fn time_at_station(s: &[f64], v: &[f64], dt: f64, station: f64) -> Option<f64> {
    let first = *s.first()?;
    if first >= station {
        return Some(0.0);
    }
    for (k, w) in s.windows(2).enumerate() {
        if let [a, b] = w
            && *b >= station
        {
            let frac = if b > a { (station - a) / (b - a) } else { 1.0 };
            return Some((k as f64 + frac) * dt);
        }
    }
    let (s_n, v_n) = (*s.last()?, *v.last()?);
    (v_n > 1e-3).then(|| (s.len() - 1) as f64 * dt + (station - s_n) / v_n)
}

fn set(v: &mut [f64], i: usize, x: f64) {
    if let Some(e) = v.get_mut(i) {
        *e = x;
    }
}

fn nz_index(m: &CscMatrix<f64>, row: usize, col: usize) -> Option<usize> {
    let (start, end) = (*m.colptr.get(col)?, *m.colptr.get(col + 1)?);
    (start..end).find(|&i| m.rowval.get(i) == Some(&row))
}

/// A CSC matrix from `(row, col, value)` triplets (duplicates summed), keeping explicit zeros.
fn csc_from_triplets(m: usize, n: usize, trip: &[(usize, usize, f64)]) -> CscMatrix<f64> {
    let mut sorted: Vec<(usize, usize, f64)> = trip.to_vec();
    sorted.sort_by_key(|x| (x.1, x.0));
    let mut colptr = vec![0usize; n + 1];
    let mut rowval: Vec<usize> = Vec::with_capacity(sorted.len());
    let mut nzval: Vec<f64> = Vec::with_capacity(sorted.len());
    let mut last: Option<(usize, usize)> = None;
    for (r, c, v) in sorted {
        if last == Some((r, c)) {
            if let Some(x) = nzval.last_mut() {
                *x += v;
            }
            continue;
        }
        rowval.push(r);
        nzval.push(v);
        if let Some(cp) = colptr.get_mut(c + 1) {
            *cp += 1;
        }
        last = Some((r, c));
    }
    for j in 0..n {
        let prev = colptr.get(j).copied().unwrap_or(0);
        if let Some(cp) = colptr.get_mut(j + 1) {
            *cp += prev;
        }
    }
    CscMatrix::new(m, n, colptr, rowval, nzval)
}

#[cfg(test)]
mod tests;
