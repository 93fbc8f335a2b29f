//! The three trajectory file formats of evo (`tum`, `kitti`, `euroc`): detection from the
//! content, reading with optional KITTI times, KITTI writing, and index pairing of files
//! without timestamps.

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::str::FromStr;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use super::{
    data_lines, parse_kitti_poses, parse_numbers, parse_times, parse_tum, read_text, Trajectory,
    TrajectoryError,
};

/// Smallest number of digits of an integer first field read as a nanosecond stamp (EuRoC);
/// seconds since 1970 have 10 digits, nanoseconds 19.
const NANOSECOND_DIGITS: usize = 16;

/// A trajectory file format, as evo names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrajectoryFormat {
    /// `t tx ty tz qx qy qz qw` per line (seconds, metres, scalar-last quaternion).
    Tum,
    /// 12 numbers per line, the row-major 3x4 `[R | t]` of `T_wc`; no timestamps.
    Kitti,
    /// EuRoC ground-truth CSV: `timestamp [ns], px, py, pz, qw, qx, qy, qz, ...` (extra
    /// columns ignored), stamps converted to seconds (`ns / 1e9`).
    Euroc,
}

impl TrajectoryFormat {
    /// The name: `tum`, `kitti` or `euroc`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Tum => "tum",
            Self::Kitti => "kitti",
            Self::Euroc => "euroc",
        }
    }

    /// The format of trajectory text, from its content: a header comment naming EuRoC's
    /// columns (`p_RS_R_x` or `q_RS_w`) means EuRoC; otherwise the first data line decides:
    /// 12 fields KITTI, at least 8 comma-separated fields whose first is an integer of 16
    /// digits or more (a nanosecond stamp) EuRoC, 8 fields TUM. `None` when nothing fits (or no data line).
    pub fn detect(text: &str) -> Option<Self> {
        let header = text
            .lines()
            .map(str::trim)
            .take_while(|l| l.is_empty() || l.starts_with('#'))
            .any(|l| l.contains("p_RS_R_x") || l.contains("q_RS_w"));
        if header {
            return Some(Self::Euroc);
        }
        let (line, fields) = data_lines(text).next()?;
        let comma = text.lines().nth(line - 1).is_some_and(|l| l.contains(','));
        let nanoseconds = comma
            && fields[0].len() >= NANOSECOND_DIGITS
            && fields[0].bytes().all(|b| b.is_ascii_digit());
        match fields.len() {
            12 => Some(Self::Kitti),
            n if n >= 8 && nanoseconds => Some(Self::Euroc),
            8 => Some(Self::Tum),
            _ => None,
        }
    }
}

impl FromStr for TrajectoryFormat {
    type Err = String;

    /// `tum`, `kitti` or `euroc` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "tum" => Ok(Self::Tum),
            "kitti" => Ok(Self::Kitti),
            "euroc" => Ok(Self::Euroc),
            _ => Err(format!(
                "unknown trajectory format '{s}' (known: tum, kitti, euroc)"
            )),
        }
    }
}

/// A trajectory read from a file of any [`TrajectoryFormat`].
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryFile {
    /// The poses; a KITTI file read without times is stamped with the pose index (0, 1, ...).
    pub trajectory: Trajectory,
    /// The format it was read as.
    pub format: TrajectoryFormat,
    /// False for a KITTI file read without times: the stamps are indices, not times.
    pub timed: bool,
}

impl TrajectoryFile {
    /// Reads `path` as `format` (`None`: [`TrajectoryFormat::detect`]); `times` (one stamp in
    /// seconds per line, as KITTI's `times.txt`) stamps a KITTI file and is refused for the
    /// other formats, which carry their own stamps.
    pub fn read(
        path: &Path,
        format: Option<TrajectoryFormat>,
        times: Option<&Path>,
    ) -> Result<Self, TrajectoryError> {
        let text = read_text(path)?;
        let format = match format {
            Some(f) => f,
            None => TrajectoryFormat::detect(&text).ok_or_else(|| TrajectoryError::Parse {
                path: path.to_path_buf(),
                line: data_lines(&text).next().map_or(1, |(line, _)| line),
                message: "unknown trajectory format: expected TUM (8 fields), KITTI (12 \
                          numbers) or EuRoC CSV (nanosecond stamps)"
                    .into(),
            })?,
        };
        if times.is_some() && format != TrajectoryFormat::Kitti {
            return Err(TrajectoryError::TimesNotKitti {
                path: path.to_path_buf(),
                format: format.name(),
            });
        }
        let trajectory = match format {
            TrajectoryFormat::Tum => parse_tum(&text, path)?,
            TrajectoryFormat::Euroc => parse_euroc(&text, path)?,
            TrajectoryFormat::Kitti => {
                let stamps = times.map(|t| parse_times(&read_text(t)?, t)).transpose()?;
                kitti_with_times(parse_kitti_poses(&text, path)?, stamps)?
            }
        };
        Ok(Self {
            trajectory,
            format,
            timed: format != TrajectoryFormat::Kitti || times.is_some(),
        })
    }
}

/// KITTI poses stamped with `stamps`, or with their index without.
pub(super) fn kitti_with_times(
    poses: Vec<Isometry3<f64>>,
    stamps: Option<Vec<f64>>,
) -> Result<Trajectory, TrajectoryError> {
    let stamps = stamps.unwrap_or_else(|| (0..poses.len()).map(|i| i as f64).collect());
    if stamps.len() != poses.len() {
        return Err(TrajectoryError::CountMismatch {
            poses: poses.len(),
            times: stamps.len(),
        });
    }
    Ok(Trajectory::new(stamps.into_iter().zip(poses).collect()))
}

/// Makes two trajectories comparable when one or both have no timestamps (KITTI without
/// times): they are then matched by index, which needs equal lengths
/// ([`TrajectoryError::IndexMismatch`] otherwise), and the untimed one takes the other's
/// stamps (both untimed: the indices stay). Timed pairs are returned unchanged, to be
/// associated by time.
pub fn pair_untimed(
    reference: TrajectoryFile,
    estimate: TrajectoryFile,
) -> Result<(Trajectory, Trajectory), TrajectoryError> {
    let (mut r, mut e) = (reference.trajectory, estimate.trajectory);
    if reference.timed && estimate.timed {
        return Ok((r, e));
    }
    if r.len() != e.len() {
        return Err(TrajectoryError::IndexMismatch {
            reference: r.len(),
            estimate: e.len(),
        });
    }
    let restamp = |to: &mut Trajectory, from: &Trajectory| {
        for (p, q) in to.poses.iter_mut().zip(&from.poses) {
            p.0 = q.0;
        }
    };
    if !reference.timed && estimate.timed {
        restamp(&mut r, &e);
    } else if reference.timed {
        restamp(&mut e, &r);
    }
    Ok((r, e))
}

fn parse_euroc(text: &str, path: &Path) -> Result<Trajectory, TrajectoryError> {
    let err = |line, message: String| TrajectoryError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut traj = Trajectory::default();
    for (line, fields) in data_lines(text) {
        if fields.len() < 8 {
            return Err(err(
                line,
                format!(
                    "expected at least 8 fields `t[ns] px py pz qw qx qy qz`, found {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_numbers(&fields[..8]).map_err(|m| err(line, m))?;
        let q = Quaternion::new(v[4], v[5], v[6], v[7]);
        if q.norm() < 1e-6 {
            return Err(err(line, "zero quaternion".into()));
        }
        let pose = Isometry3::from_parts(
            Translation3::new(v[1], v[2], v[3]),
            UnitQuaternion::from_quaternion(q),
        );
        traj.push(v[0] / 1e9, pose);
    }
    Ok(traj)
}

impl Trajectory {
    /// The poses as KITTI text: per pose one line of the 12 numbers of the row-major 3x4
    /// `[R | t]` of `T_wc`, `%.9f`; the timestamps are not written (see
    /// [`Trajectory::to_times_string`]).
    pub fn to_kitti_string(&self) -> String {
        let mut s = String::with_capacity(self.poses.len() * 140);
        for (_, pose) in &self.poses {
            let m = pose.to_homogeneous();
            let values: Vec<String> = (0..3)
                .flat_map(|r| (0..4).map(move |c| (r, c)))
                .map(|(r, c)| format!("{:.9}", m[(r, c)]))
                .collect();
            writeln!(s, "{}", values.join(" ")).expect("writing to a String cannot fail");
        }
        s
    }

    /// The timestamps as a KITTI `times.txt`: one `%.6f` stamp (seconds) per line.
    pub fn to_times_string(&self) -> String {
        let mut s = String::with_capacity(self.poses.len() * 20);
        for (t, _) in &self.poses {
            writeln!(s, "{t:.6}").expect("writing to a String cannot fail");
        }
        s
    }

    /// Writes the poses as a KITTI file (see [`Trajectory::to_kitti_string`]).
    pub fn write_kitti(&self, path: &Path) -> Result<(), TrajectoryError> {
        fs::write(path, self.to_kitti_string()).map_err(|source| TrajectoryError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}
