//! Published camera calibrations, selectable by name (`--camera PRESET`).
//!
//! Sources: the TUM RGB-D benchmark's calibrated Kinect intrinsics (freiburg1/2/3, the fr3
//! images are already undistorted), the KITTI odometry `calib.txt` P0 rows for the three
//! calibration days, and the EuRoC MAV `cam0/sensor.yaml`.

use vofront_core::camera::{Camera, Distortion, Lens, Pinhole};

/// One named calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPreset {
    /// The name used on the command line.
    pub name: &'static str,
    /// What it is for.
    pub description: &'static str,
    /// Intrinsics and distortion.
    pub camera: Camera,
}

const fn preset(
    name: &'static str,
    description: &'static str,
    k: [f64; 4],
    d: [f64; 5],
) -> CameraPreset {
    CameraPreset {
        name,
        description,
        camera: Camera {
            pinhole: Pinhole {
                fx: k[0],
                fy: k[1],
                cx: k[2],
                cy: k[3],
            },
            distortion: Lens::RadialTangential(Distortion {
                k1: d[0],
                k2: d[1],
                p1: d[2],
                p2: d[3],
                k3: d[4],
            }),
        },
    }
}

/// Every preset, in the order `--help` lists them.
pub const PRESETS: &[CameraPreset] = &[
    preset(
        "tum-ros",
        "ROS default for a Kinect, 640x480",
        [525.0, 525.0, 319.5, 239.5],
        [0.0; 5],
    ),
    preset(
        "tum-fr1",
        "TUM RGB-D freiburg1 (images not undistorted)",
        [517.3, 516.5, 318.6, 255.3],
        [0.2624, -0.9531, -0.0054, 0.0026, 1.1633],
    ),
    preset(
        "tum-fr2",
        "TUM RGB-D freiburg2 (images not undistorted)",
        [520.9, 521.0, 325.1, 249.7],
        [0.2312, -0.7849, -0.0033, -0.0001, 0.9172],
    ),
    preset(
        "tum-fr3",
        "TUM RGB-D freiburg3 (already undistorted)",
        [535.4, 539.2, 320.1, 247.6],
        [0.0; 5],
    ),
    preset(
        "kitti-00-02",
        "KITTI odometry sequences 00-02, left grey",
        [718.856, 718.856, 607.1928, 185.2157],
        [0.0; 5],
    ),
    preset(
        "kitti-03",
        "KITTI odometry sequence 03, left grey",
        [721.5377, 721.5377, 609.5593, 172.854],
        [0.0; 5],
    ),
    preset(
        "kitti-04-12",
        "KITTI odometry sequences 04-12, left grey",
        [707.0912, 707.0912, 601.8873, 183.1104],
        [0.0; 5],
    ),
    preset(
        "euroc",
        "EuRoC MAV cam0 (radial-tangential)",
        [458.654, 457.296, 367.215, 248.375],
        [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0],
    ),
];

/// The preset called `name`, if any.
///
/// ```
/// let fr1 = vofront::presets::camera_preset("tum-fr1").unwrap();
/// assert_eq!(fr1.camera.pinhole.fx, 517.3);
/// assert!(vofront::presets::camera_preset("nope").is_none());
/// ```
pub fn camera_preset(name: &str) -> Option<&'static CameraPreset> {
    PRESETS.iter().find(|p| p.name == name)
}

/// Largest distance between the principal point and the image centre, as a fraction of the
/// image width (x) or height (y), before [`principal_point_warning`] speaks up.
pub const CENTRE_TOLERANCE: f64 = 0.1;

/// A warning when the principal point `(cx, cy)` of `camera` is far from the centre
/// `((w - 1) / 2, (h - 1) / 2)` of a `w x h` image (more than [`CENTRE_TOLERANCE`] of the
/// width or height), naming the presets that would fit; `None` when it fits. Meant for the
/// default camera (525, 525, 319.5, 239.5: a 640x480 Kinect) meeting, say, a KITTI image.
///
/// ```
/// use vofront::presets::{camera_preset, principal_point_warning};
/// let kinect = camera_preset("tum-ros").unwrap().camera;
/// assert!(principal_point_warning(&kinect, (640, 480)).is_none());
/// let w = principal_point_warning(&kinect, (1241, 376)).unwrap();
/// assert!(w.contains("kitti-00-02"));
/// ```
pub fn principal_point_warning(camera: &Camera, (w, h): (usize, usize)) -> Option<String> {
    let fits = |c: &Camera| {
        let k = c.pinhole;
        (k.cx - (w as f64 - 1.0) / 2.0).abs() <= CENTRE_TOLERANCE * w as f64
            && (k.cy - (h as f64 - 1.0) / 2.0).abs() <= CENTRE_TOLERANCE * h as f64
    };
    if fits(camera) {
        return None;
    }
    let k = camera.pinhole;
    let candidates: Vec<&str> = PRESETS
        .iter()
        .filter(|p| fits(&p.camera))
        .map(|p| p.name)
        .collect();
    let hint = if candidates.is_empty() {
        "give --fx --fy --cx --cy".to_string()
    } else {
        format!("presets that fit: --camera {}", candidates.join(" | "))
    };
    Some(format!(
        "the camera's principal point ({:.1}, {:.1}) is far from the centre of this {w}x{h} \
         image ({:.1}, {:.1}): the pose will be wrong; {hint}",
        k.cx,
        k.cy,
        (w as f64 - 1.0) / 2.0,
        (h as f64 - 1.0) / 2.0
    ))
}
