//! Pose-graph constraints for a back-end, in g2o's text format (read by g2o, GTSAM's `readG2o`
//! and Ceres's `pose_graph_3d` example).
//!
//! [`G2oSink`] streams, flushed per line:
//! - `VERTEX_SE3:QUAT id x y z qx qy qz qw` for every keyframe: its camera-to-world pose
//!   `T_wi` (id = the frame's index in the dataset, as in the metrics CSV);
//! - `EDGE_SE3:QUAT i j x y z qx qy qz qw` + the 21 upper-triangular entries of the 6x6
//!   information matrix (row by row), between a keyframe `j` and the keyframe `i` it was
//!   tracked against, when its estimate has a 6x6 covariance.
//!
//! Frame convention (g2o's `EdgeSE3`): the measurement is `Z_ij = T_wi^-1 T_wj`, the pose of
//! keyframe `j` in keyframe `i` (it maps `j`'s camera points into `i`'s: `Z_ij = T_ji^-1` for
//! the tracker's `T_ji`); the edge error at vertex poses `X_i, X_j` is
//! `e = (t, q_xyz)` of `Z_ij^-1 X_i^-1 X_j` (translation in metres, then the vector part of the
//! unit quaternion with `q_w >= 0`), and the information is that of `e`: translation rows
//! first, then rotation. A tracker's covariance `Sigma` is that of the left increment
//! `(rho, phi)` of `T_ji` (`T_ji <- exp(delta) T_ji`), which is the right increment `-delta`
//! of `Z_ij`; to first order `e = (rho, phi / 2)`, so the information written is
//! `Omega = (S Sigma S)^-1` with `S = diag(1, 1, 1, 1/2, 1/2, 1/2)`. It is conditional on
//! keyframe `i`: the trackers hold the keyframe fixed while they align to it.
//!
//! Keyframes that (re)start tracking at a guess carry no estimate, so they get a vertex and no
//! edge (a segment break); so does a keyframe whose estimate has no 6x6 covariance (the
//! monocular initialisation's two-view pose, an unknown covariance). Frames that are not
//! keyframes are not written: each would be a leaf with a single edge, which adds nothing to
//! the keyframe poses.

use std::io::{self, Write};

use nalgebra::{Isometry3, Matrix6, Quaternion, Translation3, UnitQuaternion, Vector6};
use thiserror::Error;

use super::run::{FrameRecord, FrameSink};
use super::TrackStatus;

/// `S = diag(1, 1, 1, 1/2, 1/2, 1/2)`: from the increment `(rho, phi)` to g2o's error
/// `(t, q_xyz)` at first order.
fn tangent_to_g2o() -> Matrix6<f64> {
    Matrix6::from_diagonal(&Vector6::new(1.0, 1.0, 1.0, 0.5, 0.5, 0.5))
}

/// g2o's information of an edge whose measurement `T_ji` has the left-increment covariance
/// `covariance` (`(rho, phi)`, metres and radians): `(S Sigma S)^-1`; `None` when singular or
/// not finite.
pub fn g2o_information(covariance: &Matrix6<f64>) -> Option<Matrix6<f64>> {
    let s = tangent_to_g2o();
    let info = (s * covariance * s).try_inverse()?;
    info.iter()
        .all(|v| v.is_finite())
        .then(|| 0.5 * (info + info.transpose()))
}

/// g2o's `toVectorMQT`: translation, then the quaternion's vector part with `q_w >= 0`.
pub fn g2o_error_vector(delta: &Isometry3<f64>) -> Vector6<f64> {
    let t = delta.translation.vector;
    let q = delta.rotation.quaternion();
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    Vector6::new(t.x, t.y, t.z, sign * q.i, sign * q.j, sign * q.k)
}

/// One `EDGE_SE3:QUAT` constraint.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct G2oEdge {
    /// Vertex `i` (the keyframe tracked against).
    pub from: usize,
    /// Vertex `j`.
    pub to: usize,
    /// `Z_ij = T_wi^-1 T_wj`.
    pub measurement: Isometry3<f64>,
    /// Information of the error `(t, q_xyz)`, symmetric.
    pub information: Matrix6<f64>,
}

impl G2oEdge {
    /// g2o's error `(t, q_xyz)` of `Z_ij^-1 X_i^-1 X_j` at vertex poses `x_i`, `x_j`.
    pub fn error(&self, x_i: &Isometry3<f64>, x_j: &Isometry3<f64>) -> Vector6<f64> {
        g2o_error_vector(&(self.measurement.inverse() * x_i.inverse() * x_j))
    }

    /// The edge's chi-square `e^T Omega e` at vertex poses `x_i`, `x_j`.
    pub fn chi2(&self, x_i: &Isometry3<f64>, x_j: &Isometry3<f64>) -> f64 {
        let e = self.error(x_i, x_j);
        e.dot(&(self.information * e))
    }
}

/// The vertices and edges of a g2o file.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct G2oGraph {
    /// `(id, T_wi)` in file order.
    pub vertices: Vec<(usize, Isometry3<f64>)>,
    /// Edges in file order.
    pub edges: Vec<G2oEdge>,
}

impl G2oGraph {
    /// The pose of vertex `id`.
    pub fn vertex(&self, id: usize) -> Option<&Isometry3<f64>> {
        self.vertices.iter().find(|(v, _)| *v == id).map(|(_, p)| p)
    }
}

/// What [`parse_g2o`] refused.
#[derive(Debug, Error, PartialEq)]
pub enum G2oError {
    /// A line has the wrong number of fields or a field is not a number.
    #[error("line {line}: {why}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        why: String,
    },
}

/// `T = (x y z, qx qy qz qw)`, the quaternion normalised.
fn pose_of(v: &[f64]) -> Isometry3<f64> {
    let q = UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5]));
    Isometry3::from_parts(Translation3::new(v[0], v[1], v[2]), q)
}

/// Reads the `VERTEX_SE3:QUAT` and `EDGE_SE3:QUAT` lines of a g2o file (other tags, blank lines
/// and `#` comments are skipped).
pub fn parse_g2o(text: &str) -> Result<G2oGraph, G2oError> {
    let mut graph = G2oGraph::default();
    for (k, raw) in text.lines().enumerate() {
        let bad = |why: String| G2oError::Malformed { line: k + 1, why };
        let mut fields = raw.split_whitespace();
        let tag = fields.next().unwrap_or("");
        let (ids, numbers) = match tag {
            "VERTEX_SE3:QUAT" => (1, 7),
            "EDGE_SE3:QUAT" => (2, 7 + 21),
            _ => continue,
        };
        let rest: Vec<&str> = fields.collect();
        if rest.len() != ids + numbers {
            return Err(bad(format!(
                "{tag}: {} fields, {} expected",
                rest.len(),
                ids + numbers
            )));
        }
        let id: Vec<usize> = rest[..ids]
            .iter()
            .map(|s| s.parse().map_err(|_| bad(format!("id {s:?}"))))
            .collect::<Result<_, _>>()?;
        let v: Vec<f64> = rest[ids..]
            .iter()
            .map(|s| {
                s.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(format!("number {s:?}")))
            })
            .collect::<Result<_, _>>()?;
        if v[3..7].iter().all(|q| *q == 0.0) {
            return Err(bad("zero quaternion".into()));
        }
        if ids == 1 {
            graph.vertices.push((id[0], pose_of(&v)));
        } else {
            let mut information = Matrix6::zeros();
            let mut upper = v[7..].iter();
            for r in 0..6 {
                for c in r..6 {
                    let x = *upper.next().unwrap_or(&0.0);
                    information[(r, c)] = x;
                    information[(c, r)] = x;
                }
            }
            graph.edges.push(G2oEdge {
                from: id[0],
                to: id[1],
                measurement: pose_of(&v),
                information,
            });
        }
    }
    Ok(graph)
}

/// `x y z qx qy qz qw` of `t` (full precision).
fn pose_fields(t: &Isometry3<f64>) -> String {
    let p = t.translation.vector;
    let q = t.rotation.quaternion();
    format!("{} {} {} {} {} {} {}", p.x, p.y, p.z, q.i, q.j, q.k, q.w)
}

/// Writes the keyframe pose graph of a run as it goes (see the module documentation), one
/// flushed line at a time, so an interrupted run leaves a valid file of every keyframe so far.
#[derive(Debug)]
pub struct G2oSink<W: Write> {
    out: W,
    /// The last keyframe: its vertex id and `T_wc`.
    last: Option<(usize, Isometry3<f64>)>,
}

impl<W: Write> G2oSink<W> {
    /// A sink writing into `out` (typically a `BufWriter<File>`).
    pub fn new(out: W) -> Self {
        Self { out, last: None }
    }

    fn line(&mut self, line: &str) -> io::Result<()> {
        writeln!(self.out, "{line}")?;
        self.out.flush()
    }
}

impl<W: Write> FrameSink for G2oSink<W> {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        let Ok(e) = &record.estimate else {
            return Ok(());
        };
        if !e.quality.keyframe || e.status == TrackStatus::Lost {
            return Ok(());
        }
        let id = record.index;
        self.line(&format!("VERTEX_SE3:QUAT {id} {}", pose_fields(&e.pose_wc)))?;
        let covariance = e
            .pose_quality
            .as_ref()
            .and_then(|q| q.uncertainty.covariance.as_ref())
            .filter(|rows| rows.len() == 6 && rows.iter().all(|r| r.len() == 6))
            .map(|rows| Matrix6::from_fn(|r, c| rows[r][c]));
        let tracked = matches!(e.status, TrackStatus::Ok | TrackStatus::Unreliable);
        if let (true, Some((from, t_wi)), Some(cov)) = (tracked, self.last, covariance) {
            if let Some(info) = g2o_information(&cov) {
                let upper: Vec<String> = (0..6)
                    .flat_map(|r| (r..6).map(move |c| (r, c)))
                    .map(|(r, c)| info[(r, c)].to_string())
                    .collect();
                let z = t_wi.inverse() * e.pose_wc;
                self.line(&format!(
                    "EDGE_SE3:QUAT {from} {id} {} {}",
                    pose_fields(&z),
                    upper.join(" ")
                ))?;
            }
        }
        self.last = Some((id, e.pose_wc));
        Ok(())
    }
}
