//! Which topics of a bag make the frames ([`BagTopics`]), and the pairing of depth and right
//! images with the left ones by header stamp.

use super::BagError;
use std::path::Path;

/// The topics to read from a bag; `None` picks automatically (see [`super`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BagTopics {
    /// The (left) intensity images: `sensor_msgs/msg/Image` or `CompressedImage`.
    pub image: Option<String>,
    /// The right images of a stereo pair; never picked automatically.
    pub right: Option<String>,
    /// Depth images (`16UC1`, `32FC1`).
    pub depth: Option<String>,
    /// The calibration of the image topic (`sensor_msgs/msg/CameraInfo`).
    pub camera_info: Option<String>,
}

/// The role of a topic, as named by errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// The (left) intensity images.
    Image,
    /// The right images.
    Right,
    /// The depth images.
    Depth,
    /// The calibration.
    CameraInfo,
}

impl Stream {
    /// The command-line flag that names this topic.
    pub fn flag(self) -> &'static str {
        match self {
            Stream::Image => "--image-topic",
            Stream::Right => "--right-topic",
            Stream::Depth => "--depth-topic",
            Stream::CameraInfo => "--camera-info-topic",
        }
    }
}

impl std::fmt::Display for Stream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stream::Image => "image (sensor_msgs/msg/Image or CompressedImage, not depth)",
            Stream::Right => "right image",
            Stream::Depth => "depth image (sensor_msgs/msg/Image 16UC1 or 32FC1)",
            Stream::CameraInfo => "camera info (sensor_msgs/msg/CameraInfo)",
        })
    }
}

/// The topic of `stream`: `given` when it is one of `allowed`; else, when `auto`, the one
/// candidate (`preferred` first when it is a candidate), none when there is none and `required`
/// is false; errors name the candidates.
pub fn pick(
    path: &Path,
    stream: Stream,
    given: Option<&str>,
    candidates: &[String],
    allowed: &[String],
    preferred: Option<&str>,
    required: bool,
) -> Result<Option<String>, BagError> {
    if let Some(topic) = given {
        return if allowed.iter().any(|t| t == topic) {
            Ok(Some(topic.to_owned()))
        } else {
            Err(BagError::NotFound {
                path: path.to_path_buf(),
                stream,
                topic: topic.to_owned(),
                candidates: allowed.to_vec(),
            })
        };
    }
    if let Some(p) = preferred.filter(|p| candidates.iter().any(|c| c == p)) {
        return Ok(Some(p.to_owned()));
    }
    match candidates {
        [one] => Ok(Some(one.clone())),
        [] if !required => Ok(None),
        [] => Err(BagError::NoTopic {
            path: path.to_path_buf(),
            stream,
            topics: allowed.to_vec(),
        }),
        many => Err(BagError::Ambiguous {
            path: path.to_path_buf(),
            stream,
            candidates: many.to_vec(),
        }),
    }
}

/// The ROS camera-info topic beside an image topic: `/ns/image_raw` -> `/ns/camera_info`.
pub fn sibling_camera_info(image_topic: &str) -> Option<String> {
    image_topic
        .rsplit_once('/')
        .map(|(ns, _)| format!("{ns}/camera_info"))
}

/// For each of the (sorted) `left` stamps, the index of the nearest `other` stamp (sorted)
/// within `tolerance` seconds, each `other` used at most once (a closer left frame wins).
pub fn match_stamps(left: &[f64], other: &[f64], tolerance: f64) -> Vec<Option<usize>> {
    let mut best: Vec<Option<usize>> = vec![None; left.len()];
    let mut owner: Vec<Option<usize>> = vec![None; other.len()];
    for (i, &t) in left.iter().enumerate() {
        let j = other.partition_point(|&o| o < t);
        let nearest = [j.checked_sub(1), (j < other.len()).then_some(j)]
            .into_iter()
            .flatten()
            .min_by(|&a, &b| (other[a] - t).abs().total_cmp(&(other[b] - t).abs()));
        let Some(j) = nearest.filter(|&j| (other[j] - t).abs() <= tolerance) else {
            continue;
        };
        match owner[j] {
            Some(k) if (other[j] - left[k]).abs() <= (other[j] - t).abs() => {}
            previous => {
                if let Some(k) = previous {
                    best[k] = None;
                }
                owner[j] = Some(i);
                best[i] = Some(j);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_pair_nearest_within_tolerance_once() {
        let left = [0.0, 0.1, 0.2, 0.3];
        let other = [0.001, 0.099, 0.25, 0.29];
        assert_eq!(
            match_stamps(&left, &other, 0.02),
            vec![Some(0), Some(1), None, Some(3)]
        );
        // Two left frames nearest to one depth map: the closer keeps it.
        assert_eq!(
            match_stamps(&[0.0, 0.01], &[0.009], 0.02),
            vec![None, Some(0)]
        );
    }

    #[test]
    fn ambiguous_and_missing_topics_list_the_candidates() {
        let path = Path::new("rec.mcap");
        let two = vec!["/a/image".to_owned(), "/b/image".to_owned()];
        let err = pick(path, Stream::Image, None, &two, &two, None, true).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("/a/image")
                && text.contains("/b/image")
                && text.contains("--image-topic"),
            "{text}"
        );
        let picked = pick(
            path,
            Stream::Image,
            None,
            &two,
            &two,
            Some("/b/image"),
            true,
        )
        .unwrap();
        assert_eq!(picked.as_deref(), Some("/b/image"));
        assert!(matches!(
            pick(path, Stream::Image, Some("/c"), &two, &two, None, true),
            Err(BagError::NotFound { .. })
        ));
        assert_eq!(
            pick(path, Stream::Depth, None, &[], &two, None, false).unwrap(),
            None
        );
        assert_eq!(
            sibling_camera_info("/cam/image_raw").as_deref(),
            Some("/cam/camera_info")
        );
    }
}
