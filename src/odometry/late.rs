//! Late estimates: frames a tracker waits through, answered once it can locate them.
//!
//! A tracker that cannot place a frame yet (a monocular map waiting for parallax, a direct
//! tracker waiting for depth) reports it lost and keeps what it needs to locate it later in a
//! [`Waiting`] queue, which starts at a reference frame `since` at pose `T_w1`. Once the
//! tracker places the current frame `now` at `T_wn`, each waited frame is located from the
//! pose its index puts on the way between the two,
//! `T_w1 exp(f log(T_w1^-1 T_wn))`, `f = (frame - since) / (now - since)`, and the estimates
//! found are handed over through [`Tracker::revised`](super::Tracker::revised) by
//! [`LateEstimates`], which also counts the frames and answers
//! [`Tracker::pending`](super::Tracker::pending).

use std::time::Instant;

use nalgebra::Isometry3;

use super::FrameEstimate;

/// The pose a fraction `f` of the way along the screw motion from `t_w1` to `t_w2`:
/// `T_w1 exp(f log(T_w1^-1 T_w2))`, with the rotation and translation interpolated apart.
fn along(t_w1: &Isometry3<f64>, t_w2: &Isometry3<f64>, f: f64) -> Isometry3<f64> {
    let t_12 = t_w1.inverse() * t_w2;
    t_w1 * Isometry3::new(t_12.translation.vector * f, t_12.rotation.scaled_axis() * f)
}

/// The frames waited through since the reference frame `since`, each with what locating it
/// later takes (`T`: features, an image).
#[derive(Debug, Clone)]
pub(crate) struct Waiting<T> {
    since: usize,
    frames: Vec<(usize, T)>,
}

impl<T> Waiting<T> {
    /// An empty queue whose reference is frame `since`.
    pub fn from(since: usize) -> Self {
        Self {
            since,
            frames: Vec::new(),
        }
    }

    /// The index of the reference frame.
    pub fn since(&self) -> usize {
        self.since
    }

    /// Adds frame `frame` (after the reference) with what locating it takes.
    pub fn push(&mut self, frame: usize, item: T) {
        self.frames.push((frame, item));
    }

    /// Locates the waited frames once the current frame `now` is at `t_wn`, the reference
    /// being at `t_w1`: `locate(item, predicted, start)` is given each frame's pose on the way
    /// between the two ([`along`]) and the time its work started, and answers the frame's
    /// estimate or `None` (the frame stays lost). Returns `(frames back from now, estimate)`
    /// for those located, oldest first ([`Tracker::revised`](super::Tracker::revised)).
    pub fn locate<F>(
        &self,
        t_w1: &Isometry3<f64>,
        (now, t_wn): (usize, &Isometry3<f64>),
        mut locate: F,
    ) -> Vec<(usize, FrameEstimate)>
    where
        F: FnMut(&T, Isometry3<f64>, Instant) -> Option<FrameEstimate>,
    {
        let span = now.saturating_sub(self.since).max(1) as f64;
        self.frames
            .iter()
            .filter_map(|(frame, item)| {
                let start = Instant::now();
                let predicted = along(t_w1, t_wn, (frame - self.since) as f64 / span);
                Some((now - frame, locate(item, predicted, start)?))
            })
            .collect()
    }
}

/// The frame count of a tracker and the late estimates its last frame made: what
/// [`Tracker::pending`](super::Tracker::pending) and
/// [`Tracker::revised`](super::Tracker::revised) answer.
#[derive(Debug, Clone, Default)]
pub(crate) struct LateEstimates {
    /// Index of the frame being tracked (frames given so far before it).
    frame: usize,
    /// Late estimates made by the last frame, with their positions back from it.
    revised: Vec<(usize, FrameEstimate)>,
}

impl LateEstimates {
    /// Index of the frame being tracked (between [`begin_frame`](Self::begin_frame) and
    /// [`end_frame`](Self::end_frame); the number of frames tracked after it).
    pub fn frame(&self) -> usize {
        self.frame
    }

    /// Starts a frame: the late estimates of the one before, handed over or not, are dropped.
    pub fn begin_frame(&mut self) {
        self.revised.clear();
    }

    /// Ends a frame: the next one has the next index.
    pub fn end_frame(&mut self) {
        self.frame += 1;
    }

    /// Keeps the late estimates made by this frame (`(frames back, estimate)`) to hand over.
    pub fn hand_over(&mut self, revised: Vec<(usize, FrameEstimate)>) {
        self.revised = revised;
    }

    /// The frames after the reference of `waiting` tracked so far (0 when nothing waits):
    /// [`Tracker::pending`](super::Tracker::pending) after a frame.
    pub fn pending<T>(&self, waiting: Option<&Waiting<T>>) -> usize {
        waiting.map_or(0, |w| self.frame.saturating_sub(w.since + 1))
    }

    /// The late estimates of the last frame, handed over once
    /// ([`Tracker::revised`](super::Tracker::revised)).
    pub fn take(&mut self) -> Vec<(usize, FrameEstimate)> {
        std::mem::take(&mut self.revised)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Vector3};

    use super::{along, LateEstimates, Waiting};
    use crate::odometry::FrameEstimate;

    #[test]
    fn along_runs_from_the_first_pose_to_the_second() {
        let t_w1 = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.1, 0.2, -0.3));
        let t_w2 = t_w1 * Isometry3::new(Vector3::new(0.0, 0.0, 4.0), Vector3::new(0.0, 0.08, 0.0));
        assert!((along(&t_w1, &t_w2, 0.0).to_homogeneous() - t_w1.to_homogeneous()).norm() < 1e-12);
        assert!((along(&t_w1, &t_w2, 1.0).to_homogeneous() - t_w2.to_homogeneous()).norm() < 1e-12);
        let half = t_w1.inverse() * along(&t_w1, &t_w2, 0.5);
        assert!((half.translation.vector - Vector3::new(0.0, 0.0, 2.0)).norm() < 1e-12);
        assert!((half.rotation.angle() - 0.04).abs() < 1e-12);
    }

    /// Frames 3 and 4 wait on reference 2; at frame 6 (4 m on) frame 3 is located 1 m on and
    /// frame 4 is not located: one revision, 3 frames back; pending counts frames 3 to 6.
    #[test]
    fn waited_frames_are_located_on_the_way_and_handed_over_once() {
        let mut late = LateEstimates::default();
        let mut waiting = Waiting::from(2);
        for frame in 0..7 {
            late.begin_frame();
            assert_eq!(late.frame(), frame);
            if frame == 3 || frame == 4 {
                waiting.push(frame, frame == 3);
            }
            if frame == 6 {
                let t_wn = Isometry3::translation(0.0, 0.0, 4.0);
                let revised = waiting.locate(&Isometry3::identity(), (6, &t_wn), |ok, t, start| {
                    ok.then(|| FrameEstimate::lost(t, "late".into(), start))
                });
                late.hand_over(revised);
            }
            late.end_frame();
        }
        assert_eq!(late.pending(Some(&waiting)), 4);
        assert_eq!(late.pending::<bool>(None), 0);
        let revised = late.take();
        assert_eq!(revised.len(), 1);
        assert_eq!(revised[0].0, 3);
        assert!((revised[0].1.pose_wc.translation.z - 1.0).abs() < 1e-12);
        assert!(late.take().is_empty());
    }
}
