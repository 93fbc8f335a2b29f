//! EuRoC MAV sequence folders (ASL format).
//!
//! Layout: `mav0/cam0/data.csv` (`timestamp [ns],filename` lines, `#` header),
//! `mav0/cam0/data/<filename>` (8-bit grey PNG), `mav0/cam0/sensor.yaml` with
//! `intrinsics: [fu, fv, cu, cv]` and `distortion_coefficients: [k1, k2, p1, p2]`
//! (`distortion_model: radial-tangential`, the default) or `[k1, k2, k3, k4]`
//! (`distortion_model: equidistant`, Kannala-Brandt: TUM-VI, RealSense T265 via Kalibr). Timestamps are converted from nanoseconds to
//! seconds.
//!
//! Ground truth, optional: `mav0/state_groundtruth_estimate0/data.csv`, lines
//! `t [ns], px, py, pz, qw, qx, qy, qz, ...` (further columns ignored). It is the pose of the
//! **body (IMU) frame**, `T_wb`, exposed as published in [`Dataset::ground_truth`]; the camera
//! pose is `T_wc = T_wb T_bs` with `T_BS` of `cam0/sensor.yaml` (exposed as
//! [`Dataset::camera_in_body`]). Evaluate a camera trajectory against
//! [`Dataset::camera_ground_truth`], which applies it.
//!
//! Stereo, when `mav0/cam1/data.csv` exists: `mav0/cam1/` has the layout of `cam0/` (its
//! `sensor.yaml` is required), each `cam0` frame gets the `cam1` image of the same
//! nanosecond timestamp as its right image (none when `cam1` has no such frame: the sensor
//! triggers both cameras together), and [`Dataset::rig`] is the stereo rig of the two cameras
//! with their `T_BS` (body = IMU; identity when a file gives none). Without `cam1` the rig is
//! mono, `cam0` at its `T_BS`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use vofront_core::camera::{Camera, Distortion, KannalaBrandt, Lens, Pinhole};
use vofront_core::rig::Rig;

use super::{
    csv_records, mono_rig, parse_error, read_text, CameraSource, Dataset, DatasetConfig,
    DatasetError, DatasetKind, FrameInfo,
};
use crate::trajectory::{Trajectory, TrajectoryFile, TrajectoryFormat};

/// Tolerance on `|R^T R - I|` for the rotation block of `T_BS` (published to ~1e-6).
const ROTATION_TOLERANCE: f64 = 1e-3;

impl Dataset {
    /// The ground truth as camera poses `T_wc`, the frame a tracker's trajectory is in: for
    /// EuRoC the published body poses times `T_BS`, `T_wc = T_wb T_bc`
    /// ([`Dataset::camera_in_body`]); for TUM and KITTI the ground truth as published (already
    /// camera poses). `None` without ground truth.
    pub fn camera_ground_truth(&self) -> Option<Trajectory> {
        let gt = self.ground_truth.as_ref()?;
        Some(match self.camera_in_body {
            Some(t_bc) => {
                Trajectory::new(gt.poses.iter().map(|(t, t_wb)| (*t, t_wb * t_bc)).collect())
            }
            None => gt.clone(),
        })
    }
}

/// Opens a EuRoC MAV folder (the one holding `mav0/`; see the module documentation).
pub fn open(root: &Path, config: &DatasetConfig) -> Result<Dataset, DatasetError> {
    let cam0 = read_camera_folder(&root.join("mav0/cam0"))?;
    let cam1_dir = root.join("mav0/cam1");
    let cam1 = if cam1_dir.join("data.csv").is_file() {
        Some(read_camera_folder(&cam1_dir)?)
    } else {
        None
    };
    let rights: HashMap<u64, &PathBuf> = cam1
        .iter()
        .flat_map(|c| c.frames.iter().map(|(ns, path)| (*ns, path)))
        .collect();
    let frames = cam0
        .frames
        .iter()
        .map(|(ns, image)| FrameInfo {
            timestamp: seconds(*ns),
            image: image.clone(),
            depth: None,
            right: rights.get(ns).map(|p| (*p).clone()),
        })
        .collect();
    let rig = match &cam1 {
        Some(right) => Some(
            Rig::stereo(
                cam0.camera,
                cam0.t_bs.unwrap_or_else(Isometry3::identity),
                right.camera,
                right.t_bs.unwrap_or_else(Isometry3::identity),
            )
            .map_err(|source| DatasetError::Rig {
                path: right.sensor.clone(),
                source,
            })?,
        ),
        None => mono_rig(Some(cam0.camera), cam0.t_bs, &cam0.sensor)?,
    };
    let gt_path = root.join("mav0/state_groundtruth_estimate0/data.csv");
    let ground_truth = if gt_path.is_file() {
        Some(TrajectoryFile::read(&gt_path, Some(TrajectoryFormat::Euroc), None)?.trajectory)
    } else {
        None
    };
    Ok(Dataset {
        kind: DatasetKind::Euroc,
        root: root.to_path_buf(),
        frames,
        camera: Some(cam0.camera),
        camera_source: Some(CameraSource::CalibrationFile(cam0.sensor)),
        depth_scale: None,
        ground_truth,
        ground_truth_tolerance: config.ground_truth_tolerance,
        camera_in_body: cam0.t_bs,
        rig,
        bag: Default::default(),
    })
}

/// One camera folder (`mav0/camN/`): calibration and frame list.
struct CameraFolder {
    /// Its `sensor.yaml`.
    sensor: PathBuf,
    /// Intrinsics and lens.
    camera: Camera,
    /// `T_BS`, if given.
    t_bs: Option<Isometry3<f64>>,
    /// `(timestamp [ns], image file)` in list order.
    frames: Vec<(u64, PathBuf)>,
}

/// Reads `sensor.yaml` and `data.csv` of the camera folder `cam`.
fn read_camera_folder(cam: &Path) -> Result<CameraFolder, DatasetError> {
    let sensor = cam.join("sensor.yaml");
    if !sensor.is_file() {
        return Err(DatasetError::MissingCalibration { path: sensor });
    }
    let (camera, t_bs) = read_sensor_yaml(&sensor)?;
    let list = cam.join("data.csv");
    let frames = csv_records(&list)?
        .into_iter()
        .map(
            |(line, record)| match record.iter().collect::<Vec<_>>().as_slice() {
                [stamp, file] => Ok((
                    nanoseconds(stamp).map_err(|m| parse_error(&list, line, m))?,
                    cam.join("data").join(file),
                )),
                _ => Err(parse_error(
                    &list,
                    line,
                    format!(
                        "expected `timestamp [ns],filename`, found {} fields",
                        record.len()
                    ),
                )),
            },
        )
        .collect::<Result<Vec<_>, _>>()?;
    Ok(CameraFolder {
        sensor,
        camera,
        t_bs,
        frames,
    })
}

/// An integer nanosecond timestamp.
fn nanoseconds(field: &str) -> Result<u64, String> {
    field
        .parse()
        .map_err(|_| format!("`{field}` is not a timestamp in nanoseconds"))
}

/// Seconds from nanoseconds, split to keep full precision.
fn seconds(ns: u64) -> f64 {
    (ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9
}

/// The camera of `sensor.yaml` (`intrinsics: [fu, fv, cu, cv]`,
/// `distortion_coefficients: [k1, k2, p1, p2]` for `radial-tangential` (also when
/// `distortion_model` is absent), `[k1, k2, k3, k4]` for `equidistant`) and its optional
/// `T_BS` (`data:` list of 16 numbers, row-major 4x4).
fn read_sensor_yaml(path: &Path) -> Result<(Camera, Option<Isometry3<f64>>), DatasetError> {
    let text = read_text(path)?;
    let sensor: SensorYaml = serde_yaml_ng::from_str(&yaml_body(&text)).map_err(|e| {
        let line = e.location().map_or(0, |l| l.line());
        parse_error(path, line, e.to_string())
    })?;
    let count = |key: &str, v: &[f64], n: usize| {
        if v.len() == n {
            Ok(())
        } else {
            Err(parse_error(
                path,
                0,
                format!("`{key}` needs {n} numbers, found {}", v.len()),
            ))
        }
    };
    let (k, d) = (&sensor.intrinsics, &sensor.distortion_coefficients);
    count("intrinsics", k, 4)?;
    count("distortion_coefficients", d, 4)?;
    let camera_error = |source| DatasetError::Camera {
        path: path.to_path_buf(),
        source,
    };
    let pinhole = Pinhole::new(k[0], k[1], k[2], k[3]).map_err(camera_error)?;
    let lens = match sensor.distortion_model.as_deref() {
        None | Some("radial-tangential" | "radtan") => {
            Lens::from(Distortion::from_array([d[0], d[1], d[2], d[3], 0.0]))
        }
        Some("equidistant") => {
            Lens::from(KannalaBrandt::new([d[0], d[1], d[2], d[3]]).map_err(camera_error)?)
        }
        Some(model) => {
            return Err(parse_error(
                path,
                0,
                format!(
                    "unsupported distortion model `{model}` (radial-tangential or equidistant)"
                ),
            ))
        }
    };
    let camera = Camera::new(pinhole, lens);
    let t_bs = match &sensor.t_bs {
        Some(m) => {
            count("T_BS.data", &m.data, 16)?;
            Some(rigid_from_rows(path, &m.data)?)
        }
        None => None,
    };
    Ok((camera, t_bs))
}

/// The entries of `sensor.yaml` that the reader uses (others are ignored).
#[derive(Debug, serde::Deserialize)]
struct SensorYaml {
    /// `[fu, fv, cu, cv]`, pixels.
    intrinsics: Vec<f64>,
    /// `[k1, k2, p1, p2]` (radial-tangential) or `[k1, k2, k3, k4]` (equidistant).
    distortion_coefficients: Vec<f64>,
    /// `radial-tangential` (`radtan`; the default) or `equidistant` (Kannala-Brandt).
    #[serde(default)]
    distortion_model: Option<String>,
    /// Camera-to-body transform.
    #[serde(rename = "T_BS", default)]
    t_bs: Option<MatrixYaml>,
}

/// An OpenCV-style matrix entry: `data` row-major.
#[derive(Debug, serde::Deserialize)]
struct MatrixYaml {
    data: Vec<f64>,
}

/// `text` without what a YAML 1.2 parser rejects in OpenCV-written files: the `%YAML:1.0`
/// directive (replaced by an empty line so that line numbers stay) and `!!opencv-matrix` tags.
fn yaml_body(text: &str) -> String {
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with("%YAML") {
                ""
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        .replace("!!opencv-matrix", "")
}

/// The rigid transform of a row-major 4x4 matrix whose rotation block must be a rotation.
fn rigid_from_rows(path: &Path, m: &[f64]) -> Result<Isometry3<f64>, DatasetError> {
    let r = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    if (r.transpose() * r - Matrix3::identity()).norm() > ROTATION_TOLERANCE
        || r.determinant() <= 0.0
    {
        return Err(parse_error(
            path,
            0,
            "T_BS rotation block is not a rotation",
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(m[3], m[7], m[11]),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn camera_ground_truth_applies_t_bs_to_the_body_poses() {
        let t_wb = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, -0.2, 0.3));
        let t_bc = Isometry3::new(
            Vector3::new(-0.02, -0.06, 0.01),
            Vector3::new(0.0, 0.0, 1.5),
        );
        let mut data = Dataset {
            kind: DatasetKind::Euroc,
            root: "x".into(),
            frames: Vec::new(),
            camera: None,
            camera_source: None,
            depth_scale: None,
            ground_truth: Some(Trajectory::new(vec![(5.0, t_wb)])),
            ground_truth_tolerance: 0.02,
            camera_in_body: Some(t_bc),
            bag: Default::default(),
            rig: None,
        };
        let cam = data.camera_ground_truth().unwrap();
        // A point at the camera centre lands on the camera's world position T_wb * t_bc.
        let centre = cam.poses[0].1 * nalgebra::Point3::origin();
        assert!((centre - t_wb * nalgebra::Point3::from(t_bc.translation.vector)).norm() < 1e-12);
        assert!(
            cam.poses[0]
                .1
                .rotation
                .angle_to(&(t_wb.rotation * t_bc.rotation))
                < 1e-12
        );
        data.camera_in_body = None;
        assert_eq!(data.camera_ground_truth(), data.ground_truth);
    }
}
