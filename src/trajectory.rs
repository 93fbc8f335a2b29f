//! Timestamped camera trajectories: TUM, KITTI and EuRoC text formats and timestamp
//! association.
//!
//! A [`Trajectory`] is a list of `(timestamp in seconds, T_wc)` pairs, `T_wc` the
//! camera-to-world pose (`x_w = R x_c + t`).
//!
//! - TUM format: one pose per line, `timestamp tx ty tz qx qy qz qw` (metres, unit
//!   quaternion with the scalar last); `#` starts a comment line; fields may be separated by
//!   whitespace or commas. Written with `%.6f` timestamps and `%.9f` values.
//! - KITTI format: one pose per line, 12 numbers, the 3x4 row-major matrix `[R | t]` of
//!   `T_wc`; timestamps come from a separate `times.txt` (one number per line), or none.
//! - EuRoC ground-truth CSV: `timestamp [ns], px, py, pz, qw, qx, qy, qz, ...` (scalar-first
//!   quaternion, extra columns ignored), stamps turned into seconds.
//!
//! [`TrajectoryFormat::detect`] tells them apart from the content; [`TrajectoryFile::read`]
//! reads any of them and [`pair_untimed`] matches files without timestamps by index.
//!
//! ```
//! use nalgebra::{Isometry3, Vector3};
//! use vofront::trajectory::Trajectory;
//! let mut traj = Trajectory::default();
//! traj.push(0.0, Isometry3::identity());
//! traj.push(0.1, Isometry3::translation(0.5, 0.0, 0.0));
//! let text = traj.to_tum_string();
//! let back = Trajectory::from_tum_str(&text).unwrap();
//! assert_eq!(back.len(), 2);
//! assert!((back.poses[1].1.translation.vector - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-9);
//! ```

use std::fmt::Write as _;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};
use thiserror::Error;

mod formats;

pub use formats::{pair_untimed, TrajectoryFile, TrajectoryFormat};

/// Tolerance on `|R^T R - I|` (Frobenius) for a KITTI rotation block to be accepted; the
/// published poses are orthonormal to about 1e-6, so anything far off is a corrupt line.
const ROTATION_ORTHONORMALITY_TOLERANCE: f64 = 1e-3;

/// Errors of trajectory reading and writing.
#[derive(Debug, Error)]
pub enum TrajectoryError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// A line could not be parsed.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file (`<memory>` for text parsed from a string).
        path: PathBuf,
        /// One-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The KITTI pose file and its `times.txt` have different numbers of lines.
    #[error("{poses} poses but {times} timestamps")]
    CountMismatch {
        /// Number of poses.
        poses: usize,
        /// Number of timestamps.
        times: usize,
    },
    /// Timestamps were given for a file that is not in KITTI format.
    #[error("{path}: times are only for KITTI pose files, this one is {format}")]
    TimesNotKitti {
        /// The trajectory file.
        path: PathBuf,
        /// Its format name.
        format: &'static str,
    },
    /// A file without timestamps (KITTI) can only be matched by index, which needs the other
    /// trajectory to have as many poses.
    #[error(
        "a trajectory without timestamps (KITTI) is matched by index, but the reference has \
         {reference} poses and the estimate {estimate}: give its times.txt"
    )]
    IndexMismatch {
        /// Poses of the reference.
        reference: usize,
        /// Poses of the estimate.
        estimate: usize,
    },
}

/// A timestamped camera trajectory: `poses[k] = (t_k seconds, T_wc at t_k)` (`Serialize`:
/// `{"poses": [[t, {"rotation": [qi, qj, qk, qw], "translation": [x, y, z]}], ...]}`).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Trajectory {
    /// `(timestamp in seconds, camera-to-world pose)` in file order.
    pub poses: Vec<(f64, Isometry3<f64>)>,
}

impl Trajectory {
    /// A trajectory from timestamped poses.
    pub fn new(poses: Vec<(f64, Isometry3<f64>)>) -> Self {
        Self { poses }
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when there is no pose.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// Appends `(timestamp seconds, T_wc)`.
    pub fn push(&mut self, timestamp: f64, pose_wc: Isometry3<f64>) {
        self.poses.push((timestamp, pose_wc));
    }

    /// The timestamps in seconds.
    pub fn timestamps(&self) -> Vec<f64> {
        self.poses.iter().map(|(t, _)| *t).collect()
    }

    /// The camera centres `t` of `T_wc` in world coordinates (metres).
    pub fn positions(&self) -> Vec<Vector3<f64>> {
        self.poses
            .iter()
            .map(|(_, p)| p.translation.vector)
            .collect()
    }

    /// The pose whose timestamp is nearest to `t`, if within `max_dt` seconds:
    /// `(index, T_wc)`. Ties go to the earlier pose.
    pub fn nearest(&self, t: f64, max_dt: f64) -> Option<(usize, &Isometry3<f64>)> {
        nearest_index_by(&self.poses, |p| p.0, t, max_dt).map(|i| (i, &self.poses[i].1))
    }

    /// Parses TUM text (see the module documentation).
    pub fn from_tum_str(text: &str) -> Result<Self, TrajectoryError> {
        parse_tum(text, Path::new("<memory>"))
    }

    /// Reads a TUM trajectory file.
    pub fn read_tum(path: &Path) -> Result<Self, TrajectoryError> {
        parse_tum(&read_text(path)?, path)
    }

    /// The trajectory as TUM text, `%.6f` timestamps and `%.9f` values, one pose per line.
    pub fn to_tum_string(&self) -> String {
        let mut s = String::with_capacity(self.poses.len() * 96);
        for (t, pose) in &self.poses {
            let (p, q) = (pose.translation.vector, pose.rotation.coords);
            writeln!(
                s,
                "{t:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
                p.x, p.y, p.z, q.x, q.y, q.z, q.w
            )
            .expect("writing to a String cannot fail");
        }
        s
    }

    /// Writes the trajectory as a TUM file (see [`Trajectory::to_tum_string`]).
    pub fn write_tum(&self, path: &Path) -> Result<(), TrajectoryError> {
        fs::write(path, self.to_tum_string()).map_err(|source| TrajectoryError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads KITTI poses (12 numbers per line, 3x4 row-major `T_wc`), stamped with the
    /// lines of `times` (seconds, one per line) or, without it, with the pose index.
    pub fn read_kitti(poses: &Path, times: Option<&Path>) -> Result<Self, TrajectoryError> {
        let mats = parse_kitti_poses(&read_text(poses)?, poses)?;
        let stamps = times
            .map(|tp| parse_times(&read_text(tp)?, tp))
            .transpose()?;
        formats::kitti_with_times(mats, stamps)
    }
}

/// Associates the timestamps of two trajectories, as evo's `associate_trajectories`
/// (nearest-time method, zero offset): for each pose of the shorter trajectory (the second
/// one when both have equal length), the pose of the other whose timestamp is closest, if
/// within `max_dt` seconds (evo's default `max_diff` is 0.01 s).
///
/// Returns index pairs `(index in a, index in b)`, ordered as the shorter trajectory. The
/// matching is made one-to-one: if two poses pick the same partner, only the closer pair is
/// kept (the earlier on a tie). evo keeps both in that case, which can only happen when two
/// timestamps of the shorter trajectory are less than `2 max_dt` apart; otherwise the result
/// equals evo's.
pub fn associate(a: &Trajectory, b: &Trajectory, max_dt: f64) -> Vec<(usize, usize)> {
    associate_stamps(&a.timestamps(), &b.timestamps(), max_dt)
}

/// [`associate`] on bare timestamp lists (seconds).
pub fn associate_stamps(a: &[f64], b: &[f64], max_dt: f64) -> Vec<(usize, usize)> {
    let b_longer = b.len() > a.len();
    let (short, long) = if b_longer { (a, b) } else { (b, a) };
    // (short index, long index, |dt|) in short order, one best partner per short stamp.
    let candidates: Vec<(usize, usize, f64)> = short
        .iter()
        .enumerate()
        .filter_map(|(i, &t)| nearest_index(long, t, max_dt).map(|j| (i, j, (long[j] - t).abs())))
        .collect();
    let mut best_for_long: Vec<Option<usize>> = vec![None; long.len()];
    for (k, &(_, j, dt)) in candidates.iter().enumerate() {
        match best_for_long[j] {
            Some(prev) if candidates[prev].2 <= dt => {}
            _ => best_for_long[j] = Some(k),
        }
    }
    candidates
        .iter()
        .enumerate()
        .filter(|&(k, &(_, j, _))| best_for_long[j] == Some(k))
        .map(|(_, &(i, j, _))| if b_longer { (i, j) } else { (j, i) })
        .collect()
}

/// Index of the stamp of `stamps` nearest to `t` within `max_dt`, with evo's rules: binary
/// search on sorted stamps (the later neighbour wins only when strictly closer), linear
/// search (first minimum) otherwise.
pub(crate) fn nearest_index(stamps: &[f64], t: f64, max_dt: f64) -> Option<usize> {
    nearest_index_by(stamps, |s| *s, t, max_dt)
}

/// [`nearest_index`] on items whose timestamp is `stamp(item)`.
fn nearest_index_by<T>(
    items: &[T],
    stamp: impl Fn(&T) -> f64,
    t: f64,
    max_dt: f64,
) -> Option<usize> {
    let (first, last) = (stamp(items.first()?), stamp(items.last()?));
    if !items.windows(2).all(|w| stamp(&w[1]) >= stamp(&w[0])) {
        let (j, d) = items.iter().map(|s| (stamp(s) - t).abs()).enumerate().fold(
            (0, f64::INFINITY),
            |best, (j, d)| {
                if d < best.1 {
                    (j, d)
                } else {
                    best
                }
            },
        );
        return (d <= max_dt).then_some(j);
    }
    if t < first - max_dt || t > last + max_dt {
        return None;
    }
    let upper = items
        .partition_point(|s| stamp(s) <= t)
        .min(items.len() - 1);
    let diff_ub = stamp(&items[upper]) - t;
    let diff_lb = if upper > 0 {
        t - stamp(&items[upper - 1])
    } else {
        f64::INFINITY
    };
    if diff_ub <= max_dt && diff_ub < diff_lb {
        Some(upper)
    } else if diff_lb <= max_dt && diff_lb <= diff_ub {
        Some(upper - 1)
    } else {
        None
    }
}

pub(crate) fn read_text(path: &Path) -> Result<String, TrajectoryError> {
    fs::read_to_string(path).map_err(|source| TrajectoryError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The non-empty, non-comment lines of `text` as `(one-based line number, fields)`, fields
/// split on whitespace and commas.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(i, line)| {
        let line = line.trim_start_matches('\u{feff}').trim();
        if line.is_empty() || line.starts_with('#') {
            return None;
        }
        let fields = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|f| !f.is_empty())
            .collect();
        Some((i + 1, fields))
    })
}

/// Parses all fields as finite numbers, or a message naming the bad one.
pub(crate) fn parse_numbers(fields: &[&str]) -> Result<Vec<f64>, String> {
    fields
        .iter()
        .map(|f| match f.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("`{f}` is not a finite number")),
        })
        .collect()
}

fn parse_tum(text: &str, path: &Path) -> Result<Trajectory, TrajectoryError> {
    let err = |line, message: String| TrajectoryError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut traj = Trajectory::default();
    for (line, fields) in data_lines(text) {
        if fields.len() != 8 {
            return Err(err(
                line,
                format!(
                    "expected 8 fields `t tx ty tz qx qy qz qw`, found {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_numbers(&fields).map_err(|m| err(line, m))?;
        let q = Quaternion::new(v[7], v[4], v[5], v[6]);
        if q.norm() < 1e-6 {
            return Err(err(line, "zero quaternion".into()));
        }
        let pose = Isometry3::from_parts(
            Translation3::new(v[1], v[2], v[3]),
            UnitQuaternion::from_quaternion(q),
        );
        traj.push(v[0], pose);
    }
    Ok(traj)
}

fn parse_kitti_poses(text: &str, path: &Path) -> Result<Vec<Isometry3<f64>>, TrajectoryError> {
    let err = |line, message: String| TrajectoryError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };
    data_lines(text)
        .map(|(line, fields)| {
            if fields.len() != 12 {
                return Err(err(
                    line,
                    format!(
                        "expected 12 numbers (3x4 row-major), found {}",
                        fields.len()
                    ),
                ));
            }
            let v = parse_numbers(&fields).map_err(|m| err(line, m))?;
            kitti_pose(&v).map_err(|m| err(line, m))
        })
        .collect()
}

/// The pose `T_wc` of a KITTI row: 12 numbers, the row-major 3x4 `[R | t]`; an error message
/// when there are not 12 finite numbers or the 3x3 block is not a rotation (to 1e-3).
pub fn kitti_pose(v: &[f64]) -> Result<Isometry3<f64>, String> {
    if v.len() != 12 || !v.iter().all(|x| x.is_finite()) {
        return Err(format!("expected 12 finite numbers, found {}", v.len()));
    }
    let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    if (r.transpose() * r - Matrix3::identity()).norm() > ROTATION_ORTHONORMALITY_TOLERANCE
        || r.determinant() <= 0.0
    {
        return Err("the 3x3 block is not a rotation".into());
    }
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Isometry3::from_parts(
        Translation3::new(v[3], v[7], v[11]),
        q,
    ))
}

/// Parses a `times.txt`: one timestamp (seconds) per line.
pub(crate) fn parse_times(text: &str, path: &Path) -> Result<Vec<f64>, TrajectoryError> {
    data_lines(text)
        .map(|(line, fields)| {
            let parsed = match fields.as_slice() {
                [one] => parse_numbers(&[one]).map(|v| v[0]),
                _ => Err(format!(
                    "expected one timestamp, found {} fields",
                    fields.len()
                )),
            };
            parsed.map_err(|message| TrajectoryError::Parse {
                path: path.to_path_buf(),
                line,
                message,
            })
        })
        .collect()
}
