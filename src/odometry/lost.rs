//! What a sequential tracker keeps of the map it lost, and relocation into it.
//!
//! When tracking against a map `M` fails, the map is kept with the motion model's step length
//! at that moment (map units per frame). Each later frame first tries the lost map
//! ([`LostMap::relocate`], from the coasting prediction): after a short fault (a dark, blurred
//! or corrupt frame) the map is tracked again with its points and, in monocular, its scale.
//! Otherwise the tracker restarts, and a new map may take the lost one's scale
//! ([`LostMap::take`]: joined where the maps share points) or, where they do not, its step
//! length ([`LostMap::step`]) so that the trajectory keeps its speed.

/// The map tracking was lost on, and the motion model's step length when it was.
#[derive(Debug, Clone)]
pub(crate) struct LostMap<M> {
    map: Option<M>,
    step: Option<f64>,
}

impl<M> Default for LostMap<M> {
    fn default() -> Self {
        Self {
            map: None,
            step: None,
        }
    }
}

impl<M> LostMap<M> {
    /// Tracking on `map` was lost with the motion model's typical `step` (map units per
    /// frame, [`ConstantVelocity::step_length`](super::motion::ConstantVelocity::step_length)).
    pub fn lose(&mut self, map: M, step: Option<f64>) {
        self.map = Some(map);
        self.step = step;
    }

    /// The lost map, if it was not taken back.
    pub fn map(&self) -> Option<&M> {
        self.map.as_ref()
    }

    /// Takes the lost map back (to join a new map's scale to it); the step length stays.
    pub fn take(&mut self) -> Option<M> {
        self.map.take()
    }

    /// The motion model's step length at the last loss.
    pub fn step(&self) -> Option<f64> {
        self.step
    }

    /// Relocation: the lost map, taken back, when `locates` finds the current frame in it;
    /// `None` without a lost map or when it does not (the map is kept).
    pub fn relocate(&mut self, locates: impl FnOnce(&M) -> bool) -> Option<M> {
        if locates(self.map.as_ref()?) {
            self.map.take()
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::LostMap;

    /// A frame that does not locate leaves the map for the next; one that does takes it back,
    /// and the step length of the loss stays for a later new map.
    #[test]
    fn relocation_takes_the_map_back_only_when_the_frame_locates() {
        let mut lost = LostMap::default();
        assert_eq!(lost.relocate(|_: &u32| true), None);
        lost.lose(7_u32, Some(0.5));
        assert_eq!(lost.relocate(|m| *m == 8), None);
        assert_eq!(lost.map(), Some(&7));
        assert_eq!(lost.relocate(|m| *m == 7), Some(7));
        assert_eq!(lost.map(), None);
        assert_eq!(lost.take(), None);
        assert_eq!(lost.step(), Some(0.5));
    }
}
