//! Command-line flags. Every flag named here is public interface: add, don't rename.

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand, ValueEnum};
use vofront::core::camera::{Camera, Distortion, KannalaBrandt, Lens, Pinhole};
use vofront::odometry::registry::{default_camera, TrackerKind};
use vofront::odometry::rerun_log::DEFAULT_VIEWER;
use vofront::presets::{camera_preset, principal_point_warning, PRESETS};
use vofront::trajectory::TrajectoryFormat;
use vofront::two_view::Method;

/// vofront: visual-odometry front-end. Without a command, runs the synthetic demo.
#[derive(Debug, Parser)]
#[command(name = "vofront", version, about, long_about = None)]
pub struct Cli {
    /// What to do; omitted: render a synthetic scene pair, run every method, print the errors.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Relative pose of two frames by features and by direct alignment, with pictures.
    /// Each estimate carries a verdict (ok, unreliable, failed) with reasons and sigmas.
    /// Exit code 0: at least one estimate is ok; 4: estimates printed but none is ok;
    /// 1: no estimate could be computed.
    TwoView(TwoViewArgs),
    /// Robust relative pose from given pixel correspondences (CSV x1,y1,x2,y2), as JSON with
    /// its verdict. Exit code 0: the pose is ok; 4: printed but not ok; 1: no pose at all.
    Relpose(RelposeArgs),
    /// Track a whole sequence (TUM RGB-D, KITTI or EuRoC folder) into a TUM or KITTI trajectory.
    /// Exit code 3: tracking was lost for good (partial results are still written).
    Odometry(Box<OdometryArgs>),
    /// Absolute and relative trajectory errors of an estimate against ground truth (TUM, KITTI
    /// or EuRoC files, as evo reads them).
    Eval(EvalArgs),
    /// Run every tracker the dataset allows on the same frames and compare them: ATE, RPE,
    /// frames posed and lost, time per frame; with `--out-dir` an HTML page with figures.
    Compare(Box<CompareArgs>),
}

/// Intrinsics and distortion: a preset, then individual flags override it.
#[derive(Debug, Clone, Args)]
pub struct CameraArgs {
    /// Published calibration: tum-ros, tum-fr1, tum-fr2, tum-fr3, kitti-00-02, kitti-03,
    /// kitti-04-12, euroc.
    #[arg(long, value_name = "PRESET")]
    pub camera: Option<String>,
    /// Focal length along x, pixels [default: 525].
    #[arg(long, allow_negative_numbers = true)]
    pub fx: Option<f64>,
    /// Focal length along y, pixels [default: 525].
    #[arg(long, allow_negative_numbers = true)]
    pub fy: Option<f64>,
    /// Principal point x, pixels [default: 319.5].
    #[arg(long, allow_negative_numbers = true)]
    pub cx: Option<f64>,
    /// Principal point y, pixels [default: 239.5].
    #[arg(long, allow_negative_numbers = true)]
    pub cy: Option<f64>,
    /// Distortion coefficients in the order of --dist-model: radial-tangential k1,k2,p1,p2,k3,
    /// equidistant k1,k2,k3,k4 (fewer values: the rest are 0).
    #[arg(
        long,
        value_name = "k1,k2,p1,p2,k3",
        value_delimiter = ',',
        num_args = 1,
        allow_hyphen_values = true
    )]
    pub dist: Option<Vec<f64>>,
    /// Lens model of --dist: radial-tangential (alias radtan) [default] or equidistant
    /// (Kannala-Brandt fisheye; aliases kannala-brandt, fisheye).
    #[arg(long, value_enum, value_name = "MODEL", requires = "dist")]
    pub dist_model: Option<DistModel>,
}

/// The lens model that `--dist` gives the coefficients of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DistModel {
    /// Radial-tangential (OpenCV k1,k2,p1,p2,k3).
    #[value(name = "radial-tangential", alias = "radtan")]
    RadialTangential,
    /// Kannala-Brandt equidistant (OpenCV fisheye, Kalibr equidistant: k1,k2,k3,k4).
    #[value(alias = "kannala-brandt", alias = "fisheye")]
    Equidistant,
}

impl DistModel {
    /// The lens with `coefficients` in this model's order (missing ones are 0).
    fn lens(self, coefficients: &[f64]) -> Result<Lens, String> {
        let (n, name) = match self {
            Self::RadialTangential => (5, "radial-tangential"),
            Self::Equidistant => (4, "equidistant"),
        };
        if coefficients.len() > n {
            return Err(format!(
                "--dist takes at most {n} coefficients for --dist-model {name}, got {}",
                coefficients.len()
            ));
        }
        let mut all = [0.0; 5];
        all[..coefficients.len()].copy_from_slice(coefficients);
        Ok(match self {
            Self::RadialTangential => Distortion::from_array(all).into(),
            Self::Equidistant => KannalaBrandt::new([all[0], all[1], all[2], all[3]])
                .map_err(|e| e.to_string())?
                .into(),
        })
    }
}

impl CameraArgs {
    /// True when any camera flag was given on the command line.
    pub fn is_given(&self) -> bool {
        self.camera.is_some()
            || self.fx.is_some()
            || self.fy.is_some()
            || self.cx.is_some()
            || self.cy.is_some()
            || self.dist.is_some()
    }

    /// Without any camera flag: the warning of [`principal_point_warning`] for the default
    /// camera and an image of `size`; `None` when a flag was given or the default fits.
    pub fn default_camera_warning(&self, size: (usize, usize)) -> Option<String> {
        if self.is_given() {
            return None;
        }
        let camera = self.camera().ok()?;
        principal_point_warning(&camera, size).map(|w| format!("no --camera given: {w}"))
    }

    /// The camera these flags describe.
    pub fn camera(&self) -> Result<Camera, String> {
        let base = match &self.camera {
            Some(name) => camera_preset(name).map(|p| p.camera).ok_or_else(|| {
                let names: Vec<&str> = PRESETS.iter().map(|p| p.name).collect();
                format!(
                    "unknown camera preset '{name}' (known: {})",
                    names.join(", ")
                )
            })?,
            None => default_camera(),
        };
        let k = base.pinhole;
        let pinhole = Pinhole::new(
            self.fx.unwrap_or(k.fx),
            self.fy.unwrap_or(k.fy),
            self.cx.unwrap_or(k.cx),
            self.cy.unwrap_or(k.cy),
        )
        .map_err(|e| e.to_string())?;
        let distortion = match &self.dist {
            Some(d) => self
                .dist_model
                .unwrap_or(DistModel::RadialTangential)
                .lens(d)?,
            None => base.distortion,
        };
        let camera = Camera::new(pinhole, distortion);
        camera.validate().map_err(|e| e.to_string())?;
        Ok(camera)
    }
}

/// The `--method` parser of `two-view`: the library's [`Method`] by its name, each value with
/// its help line.
fn two_view_method() -> impl TypedValueParser<Value = Method> {
    let values = Method::ALL.map(|m| {
        PossibleValue::new(m.name()).help(match m {
            Method::Feature => "ORB + essential/homography RANSAC + refinement",
            Method::Direct => "Direct 2D translation, plus SE(3) when `--depth1` is given",
            Method::All => "Both",
        })
    });
    PossibleValuesParser::new(values).try_map(|s| s.parse::<Method>())
}

/// Flags of `vofront two-view`.
#[derive(Debug, Args)]
pub struct TwoViewArgs {
    /// First frame (PNG or JPEG; colour is converted to grey).
    pub img1: PathBuf,
    /// Second frame.
    pub img2: PathBuf,
    /// Camera.
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Depth map of the first frame (16-bit PNG); enables SE(3) direct alignment.
    #[arg(long, value_name = "PNG")]
    pub depth1: Option<PathBuf>,
    /// Depth units per metre in `--depth1`.
    #[arg(long, default_value_t = 5000.0, allow_negative_numbers = true)]
    pub depth_scale: f64,
    /// Right image of frame 1, rectified with `IMG1` (needs `--baseline`): adds the metric
    /// `feature_stereo` pose (frame 2 located by PnP against frame 1's stereo points) and, without
    /// `--depth1`, the direct SE(3) alignment on frame 1's stereo depth.
    #[arg(long, value_name = "PNG", requires = "baseline")]
    pub right1: Option<PathBuf>,
    /// Stereo baseline of `--right1`, metres (the right camera at `x = +baseline`).
    #[arg(long, value_name = "M", requires = "right1")]
    pub baseline: Option<f64>,
    /// Which estimators to run.
    #[arg(long, value_parser = two_view_method(), default_value_t = Method::All)]
    pub method: Method,
    /// ORB feature budget per image.
    #[arg(long, default_value_t = 2000)]
    pub features: usize,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write pictures (keypoints, matches, differences, residuals) into this folder
    /// (`--out-dir` alone: `vofront-out/two-view`).
    #[arg(long, value_name = "DIR", num_args = 0..=1, default_missing_value = "vofront-out/two-view")]
    pub out_dir: Option<PathBuf>,
}

/// Flags of `vofront relpose`.
#[derive(Debug, Args)]
pub struct RelposeArgs {
    /// CSV with columns x1,y1,x2,y2 (pixels); extra columns ignored, header optional.
    pub matches: PathBuf,
    /// Camera.
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Print one JSON object (the keys of two-view's `feature` object and `ms`); relpose
    /// always prints JSON, the flag is accepted like every other command's.
    #[arg(long)]
    pub json: bool,
}

/// Alignment of the estimate before the errors are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AlignArg {
    /// Rigid Umeyama alignment (evo `--align`).
    Se3,
    /// Similarity alignment, for monocular estimates (evo `--align --correct_scale`).
    Sim3,
    /// Compare as given.
    None,
}

/// Unit of the RPE delta.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DeltaUnitArg {
    /// Associated poses (evo `f`).
    #[value(alias = "f")]
    Frames,
    /// Metres of travelled path (evo `m`).
    #[value(alias = "m", alias = "metres")]
    Meters,
    /// Seconds of elapsed time.
    #[value(alias = "s")]
    Seconds,
}

/// A trajectory file format (evo's names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// `timestamp tx ty tz qx qy qz qw` (seconds, metres, scalar-last quaternion).
    Tum,
    /// 12 numbers per line, row-major 3x4 `[R | t]`; no timestamps (see `--times`).
    Kitti,
    /// EuRoC ground-truth CSV: `timestamp [ns], px, py, pz, qw, qx, qy, qz, ...`.
    Euroc,
}

impl FormatArg {
    /// The library's format.
    pub fn format(self) -> TrajectoryFormat {
        match self {
            Self::Tum => TrajectoryFormat::Tum,
            Self::Kitti => TrajectoryFormat::Kitti,
            Self::Euroc => TrajectoryFormat::Euroc,
        }
    }
}

/// Flags of `vofront eval`.
#[derive(Debug, Args)]
#[command(
    after_help = "Formats are detected from the content (EuRoC header or CSV with nanosecond stamps, 12 \
numbers KITTI, 8 fields TUM) unless --format, --ref-format or --est-format says. A KITTI file \
without times is matched to the other trajectory by index (both must have as many poses); \
with --times / --ref-times / --est-times it is associated by time like the others. EuRoC \
ground truth is the body (IMU) pose and is compared as is, as evo_ape euroc does."
)]
pub struct EvalArgs {
    /// Ground-truth (reference) trajectory, camera-to-world: TUM, KITTI or EuRoC CSV.
    pub gt: PathBuf,
    /// Estimated trajectory: TUM, KITTI or EuRoC CSV.
    pub est: PathBuf,
    /// Format of both files [default: detected from each file's content].
    #[arg(long, value_enum, value_name = "FORMAT")]
    pub format: Option<FormatArg>,
    /// Format of the ground truth, overriding `--format`.
    #[arg(long, value_enum, value_name = "FORMAT", alias = "gt-format")]
    pub ref_format: Option<FormatArg>,
    /// Format of the estimate, overriding `--format`.
    #[arg(long, value_enum, value_name = "FORMAT")]
    pub est_format: Option<FormatArg>,
    /// Timestamps (seconds, one per line, as KITTI's times.txt) of every KITTI file given.
    #[arg(long, value_name = "TXT", conflicts_with_all = ["ref_times", "est_times"])]
    pub times: Option<PathBuf>,
    /// Timestamps of the ground truth when it is a KITTI file.
    #[arg(long, value_name = "TXT", alias = "gt-times")]
    pub ref_times: Option<PathBuf>,
    /// Timestamps of the estimate when it is a KITTI file.
    #[arg(long, value_name = "TXT")]
    pub est_times: Option<PathBuf>,
    /// Alignment before computing errors.
    #[arg(long, value_enum, default_value_t = AlignArg::Se3)]
    pub align: AlignArg,
    /// Largest timestamp difference for associating poses, seconds (evo `--t_max_diff`).
    #[arg(
        long,
        default_value_t = 0.01,
        allow_negative_numbers = true,
        alias = "t_max_diff"
    )]
    pub max_dt: f64,
    /// RPE: distance between the two poses of a pair, in `--delta-unit` (evo `--delta`).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub delta: f64,
    /// RPE: unit of `--delta` (evo `--delta_unit f|m`; seconds are not in evo).
    #[arg(long, value_enum, default_value_t = DeltaUnitArg::Frames, alias = "delta_unit")]
    pub delta_unit: DeltaUnitArg,
    /// RPE: every pose starts a pair, not only the previous pair's end (evo `--all_pairs`).
    #[arg(long, alias = "all_pairs")]
    pub all_pairs: bool,
    /// RPE with metres or seconds and `--all-pairs`: accepted relative miss of the delta
    /// (evo `--delta_tol`).
    #[arg(
        long,
        default_value_t = 0.1,
        allow_negative_numbers = true,
        alias = "delta_tol"
    )]
    pub delta_tol: f64,
    /// RPE: choose the pairs on the ground truth, not on the estimate (evo
    /// `--pairs_from_reference`).
    #[arg(long, alias = "pairs_from_reference")]
    pub pairs_from_reference: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write a plot (top view of both trajectories, ATE over time) to this PNG (`.svg`: SVG).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Write every figure (top and side views, ATE, RPE over time, RPE histogram) here.
    #[arg(long, value_name = "DIR", num_args = 0..=1, default_missing_value = "vofront-out/eval")]
    pub plot_dir: Option<PathBuf>,
    /// Figures of `--plot-dir` as SVG instead of PNG.
    #[arg(long)]
    pub svg: bool,
}

/// Format of the trajectory written by `vofront odometry`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OutFormat {
    /// `t tx ty tz qx qy qz qw` per tracked frame.
    Tum,
    /// 12 numbers (row-major 3x4 `T_wc`) per tracked frame, times in `<out>.times`.
    Kitti,
}

/// Flags of `vofront odometry`.
#[derive(Debug, Args)]
#[command(
    after_help = "Outputs are checked (folders created) before the first frame and \
written line by line as each frame finishes. SIGINT/SIGTERM: the frame in progress is \
finished, the summary printed, and the exit code is 130/143 (a second signal exits at once). \
Exit codes: 0 done, 1 failed, 2 bad command line, 3 tracking lost for good, 130/143 interrupted."
)]
pub struct OdometryArgs {
    /// Dataset folder: TUM RGB-D (rgb.txt), KITTI odometry (image_0/, times.txt), EuRoC (mav0/)
    /// or a plain folder of images (timed by `--fps` or by timestamp file names); or a ROS 2
    /// bag (`.mcap`, see the `--*-topic` flags).
    pub dataset: PathBuf,
    /// Tracker (`feature`, the former name of `mono`, is still accepted).
    #[arg(long, value_enum, default_value_t = TrackerKind::Direct)]
    pub method: TrackerKind,
    /// How the dataset is read: camera, depth scale, frame rate, bag topics.
    #[command(flatten)]
    pub input: DatasetArgs,
    /// ORB feature budget per frame of the feature trackers [default: the tracker's, 1000
    /// for feature-rgbd].
    #[arg(long, value_name = "N")]
    pub features: Option<usize>,
    /// Trajectory output (camera-to-world, first frame at the origin), one line per tracked
    /// frame, in `--out-format`; a name ending in `.mcap` writes a ROS 2 bag of
    /// `geometry_msgs/msg/PoseStamped` on `/vofront/pose` (frame `world`) for Foxglove instead.
    #[arg(long, value_name = "TXT", default_value = "vofront-out/trajectory.txt")]
    pub out: PathBuf,
    /// Format of `--out`: tum (`t tx ty tz qx qy qz qw`) or kitti (12 numbers per line, no
    /// timestamps; their times go to `<out>.times`, one line per pose, as KITTI's times.txt).
    #[arg(long, value_enum, value_name = "FORMAT", default_value_t = OutFormat::Tum)]
    pub out_format: OutFormat,
    /// Per-frame CSV: status, keyframe, inliers, inlier ratio, rmse, iterations, covariance
    /// trace, ms, message, verdict, reasons.
    #[arg(long, value_name = "CSV", default_value = "vofront-out/frames.csv")]
    pub metrics: PathBuf,
    /// Pose graph for a back-end, g2o format: keyframe poses (VERTEX_SE3:QUAT, T_wc) and the
    /// constraint between consecutive keyframes (EDGE_SE3:QUAT, T_ij = T_wi^-1 T_wj, 6x6
    /// information of (t, q_xyz), translation first).
    #[arg(long, value_name = "G2O")]
    pub graph: Option<PathBuf>,
    /// Plot of the trajectory against the ground truth (needs ground truth in the dataset).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// Track only the first N frames.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<usize>,
    /// Print one JSON summary object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Log every frame to a Rerun recording (open it with `rerun FILE.rrd`): the image, the
    /// keypoints (inliers green, outliers red), the camera with its pose and trajectory, the
    /// ground truth when known, the local map's points, and per-frame inliers, residual,
    /// verdict and time.
    #[arg(long, value_name = "RRD", conflicts_with = "rerun_connect")]
    pub rerun: Option<PathBuf>,
    /// Stream the same to a running Rerun viewer at ADDR.
    #[arg(
        long,
        value_name = "ADDR",
        num_args = 0..=1,
        default_missing_value = DEFAULT_VIEWER
    )]
    pub rerun_connect: Option<String>,
}

/// The topics of a ROS 2 bag (`.mcap`); each is picked automatically when the bag has exactly
/// one candidate (the right topic only when named).
#[derive(Debug, Clone, Default, Args)]
pub struct TopicArgs {
    /// `sensor_msgs/msg/Image` or `CompressedImage` topic of the (left) images.
    #[arg(long, value_name = "TOPIC")]
    pub image_topic: Option<String>,
    /// Topic of the right images of a rectified stereo pair (paired by header stamp).
    #[arg(long, value_name = "TOPIC")]
    pub right_topic: Option<String>,
    /// `16UC1` (millimetres, or `--depth-scale` units) or `32FC1` (metres) depth topic.
    #[arg(long, value_name = "TOPIC")]
    pub depth_topic: Option<String>,
    /// `sensor_msgs/msg/CameraInfo` topic: the camera unless camera flags are given
    /// [default: the one beside the image topic, else the only one].
    #[arg(long, value_name = "TOPIC")]
    pub camera_info_topic: Option<String>,
}

impl TopicArgs {
    /// The topics as the bag reader takes them.
    pub fn topics(&self) -> vofront::dataset::bag::BagTopics {
        vofront::dataset::bag::BagTopics {
            image: self.image_topic.clone(),
            right: self.right_topic.clone(),
            depth: self.depth_topic.clone(),
            camera_info: self.camera_info_topic.clone(),
        }
    }

    /// True when a topic flag was given.
    pub fn is_given(&self) -> bool {
        self.image_topic.is_some()
            || self.right_topic.is_some()
            || self.depth_topic.is_some()
            || self.camera_info_topic.is_some()
    }
}

/// How `odometry` and `compare` read their dataset.
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// Camera of the monocular and RGB-D trackers; without flags: the camera the dataset names
    /// (KITTI calib.txt, EuRoC sensor.yaml, a TUM folder name or list header), else tum-ros
    /// (the stereo trackers use the dataset's rig).
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Depth units per metre, overriding the dataset's (TUM: 5000); 8-bit and 16-bit depth
    /// PNGs are both divided by it as stored.
    #[arg(long, value_name = "UNITS", allow_negative_numbers = true)]
    pub depth_scale: Option<f64>,
    /// Frame rate (Hz) of a plain folder of images: frame `i` at `i / fps` s [default: times
    /// from the file names].
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub fps: Option<f64>,
    /// The bag topics of `dataset` when it is a ROS 2 bag (`.mcap`).
    #[command(flatten)]
    pub topics: TopicArgs,
}

impl DatasetArgs {
    /// The camera the flags give, named as their source; `None` without camera flags (the
    /// dataset's camera is used).
    pub fn given_camera(&self) -> Result<Option<(Camera, &'static str)>, String> {
        if self.camera.is_given() {
            Ok(Some((self.camera.camera()?, "command-line flags")))
        } else {
            Ok(None)
        }
    }
}

/// Flags of `vofront compare`.
#[derive(Debug, Args)]
#[command(
    after_help = "Without --methods, every tracker the dataset allows runs: the RGB-D ones \
with depth, the stereo ones with a stereo rig, the monocular ones always. With --out-dir each \
tracker's TUM trajectory is written as it is tracked, and report.json and report.html after \
each tracker, so an interrupted comparison keeps what finished. Exit codes: 0 done, 1 no \
tracker ran, 2 bad command line, 130/143 interrupted."
)]
pub struct CompareArgs {
    /// Dataset folder (TUM RGB-D, KITTI, EuRoC or a plain folder of images) or a ROS 2 bag.
    pub dataset: PathBuf,
    /// Trackers to run, comma-separated (a tracker the dataset cannot run is listed with its
    /// error) [default: every one the dataset allows].
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        num_args = 1,
        value_name = "a,b"
    )]
    pub methods: Option<Vec<TrackerKind>>,
    /// How the dataset is read: camera, depth scale, frame rate, bag topics.
    #[command(flatten)]
    pub input: DatasetArgs,
    /// ORB feature budget per frame of the feature trackers [default: each tracker's].
    #[arg(long, value_name = "N")]
    pub features: Option<usize>,
    /// Track only the first N frames.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<usize>,
    /// Print the report as one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write report.html (figures inline), report.json and each tracker's TUM trajectory
    /// (`<method>.txt`) here (`--out-dir` alone: `vofront-out/compare`).
    #[arg(long, value_name = "DIR", num_args = 0..=1, default_missing_value = "vofront-out/compare")]
    pub out_dir: Option<PathBuf>,
}
