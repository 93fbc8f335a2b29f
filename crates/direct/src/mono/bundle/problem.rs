//! The photometric residuals of a window and their Jacobians (equations in the module
//! documentation of [`super`]), as an [`LmProblem`] on a [`SchurSystem`] with 8 parameters
//! per free frame (`delta`, `a`, `b`) and one per point (`rho`).

use nalgebra::{Matrix1x3, Matrix3, SMatrix, SVector, Vector3};
use rayon::prelude::*;
use vofront_core::lie::retract_left;
use vofront_core::Pinhole;
use vofront_robust::{
    Coupling, LmProblem, Loss, PointBlock, PosePair, RobustLoss, SchurStep, SchurSystem,
};

use super::blocks::{PoseBlocks, OBSERVATIONS_PER_CHUNK};
use super::{BundleConfig, BundleFrame, BundlePoint, FrameState};
use crate::plane::sample_with_gradient;

/// Pattern pixels per observation.
pub(super) const N: usize = 8;
pub(super) type Vector8 = SVector<f64, N>;
pub(super) type Matrix8 = SMatrix<f64, N, N>;

/// The host's pattern: bearings `K^-1 (x_k, 1)` and grey levels.
pub(super) type HostPattern = Option<([Vector3<f64>; N], [f64; N])>;

/// Frame states and inverse depths.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BundleState {
    pub frames: Vec<FrameState>,
    pub rhos: Vec<f64>,
}

/// Point `point` seen in frame `target` (not its host).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Observation {
    pub point: usize,
    pub target: usize,
}

/// One observation evaluated: a residual per pattern pixel (NaN where it left the target
/// image) and its Jacobians (rows: pattern pixels; columns: `delta`, `a`, `b`).
#[derive(Debug, Clone, Copy)]
struct Row {
    pub residual: Vector8,
    pub host: Matrix8,
    pub target: Matrix8,
    pub rho: Vector8,
}

impl Row {
    fn invalid() -> Self {
        Self {
            residual: Vector8::repeat(f64::NAN),
            host: Matrix8::zeros(),
            target: Matrix8::zeros(),
            rho: Vector8::zeros(),
        }
    }
}

/// Root mean square of the finite values; `None` without any.
fn rms<'r>(values: impl Iterator<Item = &'r f64>) -> Option<f64> {
    let (sum, n) = values
        .filter(|r| r.is_finite())
        .fold((0.0, 0usize), |(s, n), r| (s + r * r, n + 1));
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// The window's photometric problem.
pub(super) struct Photometric<'a> {
    pinhole: &'a Pinhole,
    frames: &'a [BundleFrame<'a>],
    points: &'a [BundlePoint],
    patterns: &'a [HostPattern],
    cfg: &'a BundleConfig,
    loss: Loss,
    observations: Vec<Observation>,
    /// Each frame's index among the free frames (`None`: held).
    free: Vec<Option<usize>>,
    /// Observations of each point (indices into `observations`).
    by_point: Vec<Vec<usize>>,
    rows: Vec<Row>,
    saved: Vec<Row>,
    /// The brightness prior's cost at the current evaluation, and at the saved one.
    prior_cost: f64,
    saved_prior: f64,
    /// Each frame's brightness at the start (the priors' means).
    start: Vec<(f64, f64)>,
    /// The current evaluation's brightness per frame.
    brightness: Vec<(f64, f64)>,
}

impl<'a> Photometric<'a> {
    /// A problem without observations yet ([`Self::admit`]).
    pub fn new(
        pinhole: &'a Pinhole,
        frames: &'a [BundleFrame<'a>],
        points: &'a [BundlePoint],
        patterns: &'a [HostPattern],
        cfg: &'a BundleConfig,
    ) -> Self {
        Self {
            pinhole,
            frames,
            points,
            patterns,
            cfg,
            loss: Loss::Huber(1.0),
            observations: Vec::new(),
            free: Vec::new(),
            by_point: vec![Vec::new(); points.len()],
            rows: Vec::new(),
            saved: Vec::new(),
            prior_cost: 0.0,
            saved_prior: 0.0,
            start: frames.iter().map(|f| (f.state.a, f.state.b)).collect(),
            brightness: Vec::new(),
        }
    }

    /// The brightness prior's residuals `((a - a_0) / sigma_a, (b - b_0) / sigma_b)` of frame `i`
    /// at the current evaluation.
    fn prior_residual(&self, i: usize) -> (f64, f64) {
        let ((a, b), (a0, b0)) = (self.brightness[i], self.start[i]);
        ((a - a0) / self.cfg.sigma_a, (b - b0) / self.cfg.sigma_b)
    }

    /// Evaluates one observation at `state`.
    fn row(&self, state: &BundleState, o: &Observation) -> Row {
        let point = &self.points[o.point];
        let Some((bearings, grey)) = &self.patterns[o.point] else {
            return Row::invalid();
        };
        let (host, target) = (&state.frames[point.host], &state.frames[o.target]);
        let t_th = target.t_cw * host.t_cw.inverse();
        let r_th: Matrix3<f64> = t_th.rotation.to_rotation_matrix().into_inner();
        let rho = state.rhos[o.point];
        let e = (target.a - host.a).exp();
        let image = self.frames[o.target].image;
        let (w, h) = image.size();
        let border = self.cfg.border.max(1.0);
        let (umax, vmax) = (w as f32 - 1.0 - border, h as f32 - 1.0 - border);
        let k = self.pinhole;
        let mut row = Row::invalid();
        for (i, (f, &grey_h)) in bearings.iter().zip(grey).enumerate() {
            let x_h = f / rho;
            let x_t = r_th * x_h + t_th.translation.vector;
            if x_t.z <= 1e-9 {
                continue;
            }
            let iz = 1.0 / x_t.z;
            let (u, v) = (k.fx * x_t.x * iz + k.cx, k.fy * x_t.y * iz + k.cy);
            let (uf, vf) = (u as f32, v as f32);
            if !(uf >= border && vf >= border && uf <= umax && vf <= vmax) {
                continue;
            }
            let [value, gx, gy] = sample_with_gradient(image.data(), w, h, uf, vf);
            let (gx, gy) = (f64::from(gx), f64::from(gy));
            let c = grey_h - host.b;
            row.residual[i] = f64::from(value) - e * c - target.b;
            // g = grad I . d pi / d X.
            let g = Matrix1x3::new(
                gx * k.fx * iz,
                gy * k.fy * iz,
                -(gx * k.fx * x_t.x + gy * k.fy * x_t.y) * iz * iz,
            );
            let g_r = g * r_th;
            // g [I | -hat(X)] = [g, X x g] (as rows).
            let (gt, gh) = (g.transpose(), g_r.transpose());
            let (rt, rh) = (x_t.cross(&gt), x_h.cross(&gh));
            for c3 in 0..3 {
                row.target[(i, c3)] = gt[c3];
                row.target[(i, c3 + 3)] = rt[c3];
                row.host[(i, c3)] = -gh[c3];
                row.host[(i, c3 + 3)] = -rh[c3];
            }
            row.target[(i, 6)] = -e * c;
            row.target[(i, 7)] = -1.0;
            row.host[(i, 6)] = e * c;
            row.host[(i, 7)] = e;
            row.rho[i] = -(g_r * f)[0] / (rho * rho);
        }
        row
    }

    /// Keeps the `candidates` whose whole pattern is inside the target with an RMS residual
    /// of at most `max_start_rmse` at `state` (the evaluation is then at `state`), and holds
    /// the first `fixed` frames and those no kept observation involves; returns how many were
    /// kept.
    pub fn admit(&mut self, state: &BundleState, candidates: Vec<Observation>) -> usize {
        let rows: Vec<Row> = candidates.par_iter().map(|o| self.row(state, o)).collect();
        let limit = self.cfg.max_start_rmse;
        let (observations, rows): (Vec<Observation>, Vec<Row>) = candidates
            .into_iter()
            .zip(rows)
            .filter(|(_, row)| {
                row.residual.iter().all(|r| r.is_finite())
                    && (row.residual.norm_squared() / N as f64).sqrt() <= limit
            })
            .unzip();
        for list in &mut self.by_point {
            list.clear();
        }
        for (i, o) in observations.iter().enumerate() {
            self.by_point[o.point].push(i);
        }
        self.observations = observations;
        self.rows = rows;
        self.number_free_frames();
        self.observations.len()
    }

    /// Holds the first `fixed` frames and those no observation involves; numbers the rest.
    fn number_free_frames(&mut self) {
        let mut seen = vec![false; self.frames.len()];
        for o in &self.observations {
            seen[o.target] = true;
            seen[self.points[o.point].host] = true;
        }
        let mut next = 0;
        self.free = seen
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                (s && i >= self.cfg.fixed).then(|| {
                    next += 1;
                    next - 1
                })
            })
            .collect();
    }

    /// Free frames.
    fn free_frames(&self) -> usize {
        self.free.iter().flatten().count()
    }

    /// RMS residual over the valid pattern pixels of every observation, at the current
    /// evaluation.
    pub fn rmse(&self) -> f64 {
        rms(self.rows.iter().flat_map(|r| r.residual.iter())).unwrap_or(0.0)
    }

    /// Per point, the RMS residual over the valid pattern pixels of its observations at the
    /// current evaluation (NaN without any).
    pub fn point_rmse(&self) -> Vec<f64> {
        self.by_point
            .iter()
            .map(|list| {
                rms(list.iter().flat_map(|&o| self.rows[o].residual.iter())).unwrap_or(f64::NAN)
            })
            .collect()
    }

    /// Huber weights of a row's pixels (0 where invalid) and its residuals (0 where invalid).
    fn weighted(&self, row: &Row) -> (Vector8, Vector8) {
        let s = self.cfg.huber;
        let mut w = Vector8::zeros();
        let mut r = Vector8::zeros();
        for i in 0..N {
            if row.residual[i].is_finite() {
                w[i] = self.loss.weight(row.residual[i] / s);
                r[i] = row.residual[i];
            }
        }
        (w, r)
    }
}

impl LmProblem for Photometric<'_> {
    type State = BundleState;
    type System = SchurSystem<8, 1>;

    fn evaluate(&mut self, state: &BundleState) -> usize {
        self.brightness = state.frames.iter().map(|f| (f.a, f.b)).collect();
        self.prior_cost = (0..self.frames.len())
            .filter(|&i| self.free.get(i).is_some_and(|f| f.is_some()))
            .map(|i| {
                let (ra, rb) = self.prior_residual(i);
                0.5 * (ra * ra + rb * rb)
            })
            .sum();
        // Written in place: no allocation per iteration.
        let mut rows = std::mem::take(&mut self.rows);
        rows.resize(self.observations.len(), Row::invalid());
        rows.par_iter_mut()
            .zip(self.observations.par_iter())
            .for_each(|(row, o)| *row = self.row(state, o));
        self.rows = rows;
        self.rows
            .iter()
            .map(|r| r.residual.iter().filter(|v| v.is_finite()).count())
            .sum()
    }

    /// `sum s^2 rho(r / s)` and the brightness priors; a pixel that left its target costs as
    /// a residual of `max_start_rmse` (so that leaving the image does not lower the cost).
    fn cost(&self) -> f64 {
        let s = self.cfg.huber;
        let outside = s * s * self.loss.rho(self.cfg.max_start_rmse / s);
        self.prior_cost
            + self
                .rows
                .iter()
                .flat_map(|r| r.residual.iter())
                .map(|&r| {
                    if r.is_finite() {
                        s * s * self.loss.rho(r / s)
                    } else {
                        outside
                    }
                })
                .sum::<f64>()
    }

    fn linearize(&mut self) -> SchurSystem<8, 1> {
        let free = &self.free;
        let n_free = self.free_frames();
        let weighted: Vec<(Vector8, Vector8)> =
            self.rows.par_iter().map(|row| self.weighted(row)).collect();
        let points = self
            .by_point
            .par_iter()
            .enumerate()
            .map(|(j, list)| {
                let mut block = PointBlock::zeros();
                let host = free[self.points[j].host];
                let mut host_w = SVector::<f64, 8>::zeros();
                for &o in list {
                    let (row, (w, r)) = (&self.rows[o], &weighted[o]);
                    let wr = row.rho.component_mul(w);
                    block.v[(0, 0)] += wr.dot(&row.rho);
                    block.gp[0] += wr.dot(r);
                    host_w += row.host.transpose() * wr;
                    if let Some(pose) = free[self.observations[o].target] {
                        block.couplings.push(Coupling {
                            pose,
                            w: row.target.transpose() * wr,
                        });
                    }
                }
                if let Some(pose) = host {
                    block.couplings.push(Coupling { pose, w: host_w });
                }
                block
            })
            .collect();
        // Fixed chunks summed in order: the same sums whatever thread ran which chunk.
        let PoseBlocks {
            mut u,
            mut gc,
            pairs,
        } = self
            .observations
            .par_chunks(OBSERVATIONS_PER_CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut blocks = PoseBlocks::zeros(n_free);
                for (k, o) in chunk.iter().enumerate() {
                    let at = c * OBSERVATIONS_PER_CHUNK + k;
                    let h = free[self.points[o.point].host];
                    let row = &self.rows[at];
                    blocks.add((&row.host, &row.target), &weighted[at], (h, free[o.target]));
                }
                blocks
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold(PoseBlocks::zeros(n_free), PoseBlocks::merged);
        for (i, f) in free.iter().enumerate() {
            if let Some(f) = f {
                let (ra, rb) = self.prior_residual(i);
                let (sa, sb) = (self.cfg.sigma_a, self.cfg.sigma_b);
                u[*f][(6, 6)] += 1.0 / (sa * sa);
                u[*f][(7, 7)] += 1.0 / (sb * sb);
                gc[*f][6] += ra / sa;
                gc[*f][7] += rb / sb;
            }
        }
        let pairs = pairs
            .into_iter()
            .enumerate()
            .filter(|(_, m)| m.iter().any(|v| *v != 0.0))
            .map(|(idx, u)| PosePair {
                i: idx / n_free,
                k: idx % n_free,
                u,
            })
            .collect();
        SchurSystem {
            u,
            gc,
            points,
            pairs,
        }
    }

    fn retract(&self, state: &BundleState, step: &SchurStep<8, 1>) -> BundleState {
        let frames = state
            .frames
            .iter()
            .zip(&self.free)
            .map(|(f, free)| match free {
                Some(i) => {
                    let d = &step.poses[*i];
                    FrameState {
                        t_cw: retract_left(&f.t_cw, &d.fixed_rows::<6>(0).into_owned()),
                        a: f.a + d[6],
                        b: f.b + d[7],
                    }
                }
                None => *f,
            })
            .collect();
        // An inverse depth stays positive: at most a tenfold decrease per step.
        let rhos = state
            .rhos
            .iter()
            .zip(&step.points)
            .map(|(rho, d)| (rho + d[0]).max(0.1 * rho))
            .collect();
        BundleState { frames, rhos }
    }

    fn step_norm(&self, step: &SchurStep<8, 1>) -> f64 {
        step.norm()
    }

    fn save(&mut self) {
        std::mem::swap(&mut self.rows, &mut self.saved);
        self.saved_prior = self.prior_cost;
    }

    fn restore(&mut self, state: &BundleState) {
        std::mem::swap(&mut self.rows, &mut self.saved);
        self.prior_cost = self.saved_prior;
        self.brightness = state.frames.iter().map(|f| (f.a, f.b)).collect();
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Vector2, Vector3, Vector6};
    use vofront_core::lie::retract_left;
    use vofront_core::Pinhole;
    use vofront_image::Image;
    use vofront_robust::LmProblem;

    use super::{BundleState, Observation, Photometric, Row};
    use crate::mono::bundle::{host_pattern, BundleConfig, BundleFrame, BundlePoint, FrameState};

    /// The analytic Jacobians (host and target pose, brightness, inverse depth) agree with
    /// central differences of the residuals on images whose grey level is linear in the pixel
    /// (bilinear interpolation and central-difference gradients are then exact).
    #[test]
    fn jacobians_match_finite_differences() {
        let k = Pinhole::new(200.0, 210.0, 60.0, 50.0).unwrap();
        let ramp = |gx: f32, gy: f32, c: f32| {
            let data = (0..120 * 100)
                .map(|i| c + gx * (i % 120) as f32 + gy * (i / 120) as f32)
                .collect();
            Image::new(120, 100, data).unwrap()
        };
        let images = [ramp(0.9, 0.4, 10.0), ramp(-0.5, 1.1, 90.0)];
        let states = [
            FrameState {
                t_cw: Isometry3::new(
                    Vector3::new(0.1, -0.05, 0.2),
                    Vector3::new(0.02, -0.01, 0.03),
                ),
                a: 0.1,
                b: 3.0,
            },
            FrameState {
                t_cw: Isometry3::new(
                    Vector3::new(-0.05, 0.02, 0.1),
                    Vector3::new(-0.01, 0.03, 0.0),
                ),
                a: -0.2,
                b: -4.0,
            },
        ];
        let frames: Vec<BundleFrame> = images
            .iter()
            .zip(states)
            .map(|(image, state)| BundleFrame { image, state })
            .collect();
        let points = [BundlePoint {
            host: 0,
            pixel: Vector2::new(55.0, 47.0),
            rho: 0.4,
        }];
        let patterns = [host_pattern(&images[0], &k, points[0].pixel)];
        let cfg = BundleConfig {
            fixed: 0,
            max_start_rmse: 1e6,
            ..BundleConfig::default()
        };
        let problem = Photometric::new(&k, &frames, &points, &patterns, &cfg);
        let o = Observation {
            point: 0,
            target: 1,
        };
        let state = BundleState {
            frames: states.to_vec(),
            rhos: vec![0.4],
        };
        let row = problem.row(&state, &o);
        assert!(row.residual.iter().all(|r| r.is_finite()));
        // Steps large enough for the f32 image samples, small for the projection's curvature.
        let h = 1e-3;
        let difference = |plus: &BundleState, minus: &BundleState| {
            let (p, m): (Row, Row) = (problem.row(plus, &o), problem.row(minus, &o));
            (p.residual - m.residual) / (2.0 * h)
        };
        let moved = |frame: usize, c: usize, s: f64| {
            let mut st = state.clone();
            let f = &mut st.frames[frame];
            match c {
                0..=5 => {
                    let mut d = Vector6::zeros();
                    d[c] = s * h;
                    f.t_cw = retract_left(&f.t_cw, &d);
                }
                6 => f.a += s * h,
                _ => f.b += s * h,
            }
            st
        };
        for c in 0..8 {
            for (frame, analytic) in [(0, row.host.column(c)), (1, row.target.column(c))] {
                let numeric = difference(&moved(frame, c, 1.0), &moved(frame, c, -1.0));
                assert!(
                    (numeric - analytic).norm() < 2e-3 * (1.0 + analytic.norm()),
                    "frame {frame} column {c}: {numeric} vs {analytic}"
                );
            }
        }
        let (mut plus, mut minus) = (state.clone(), state.clone());
        plus.rhos[0] += h;
        minus.rhos[0] -= h;
        let numeric = difference(&plus, &minus);
        assert!(
            (numeric - row.rho).norm() < 2e-3 * (1.0 + row.rho.norm()),
            "{numeric} vs {}",
            row.rho
        );
        // The problem's own evaluation counts the eight pixels of the one observation.
        let mut problem = problem;
        assert_eq!(problem.admit(&state, vec![o]), 1);
        assert_eq!(problem.evaluate(&state), 8);
    }
}
