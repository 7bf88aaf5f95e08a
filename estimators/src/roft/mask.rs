//! Stage 1 of ROFT (thesis Sec. 5.2): optical-flow-aided segmentation.
//!
//! The synchronised mask stream `M_t` is propagated with the flow,
//! `M_t = M_{t-1} ⊞ F_t` (5.2), where `M ⊞ F` moves every pixel of `M` by its
//! flow vector (5.1). The flow frames are buffered; when a delayed mask
//! `M^d` for an earlier frame `k` arrives, it is carried forward through the
//! buffered flows `F_{k+1}, ..., F_t` (5.3) and replaces the stream.

use std::collections::VecDeque;

use super::image::{Mask, SharedFlow};

/// `M ⊞ F` (5.1): every pixel moved by its flow and rounded to the nearest
/// pixel; pixels whose flow is unknown, or that leave the image, are dropped.
pub fn propagate(mask: &Mask, flow: &super::image::FlowField) -> Mask {
    let mut out = Mask::empty(mask.width(), mask.height());
    for (u, v) in mask.pixels() {
        if let Some([du, dv]) = flow.at(u, v) {
            let (nu, nv) = ((f64::from(u) + f64::from(du)).round(), (f64::from(v) + f64::from(dv)).round());
            if nu >= 0.0 && nv >= 0.0 {
                out.insert(nu as u32, nv as u32);
            }
        }
    }
    out
}

/// What happened to a delayed mask.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DelayedMaskUse {
    /// No delayed mask this frame.
    None,
    /// Carried forward through this many buffered flow frames (5.3).
    Synchronised {
        /// Flow frames applied.
        flows: usize,
    },
    /// Used as it is (synchronisation off, or it is for the current frame).
    AsIs,
    /// Older than the flow buffer: dropped.
    TooOld,
    /// Empty or of the wrong size: dropped.
    Unusable,
}

/// The mask stream `M_t` and the buffer of flow frames `B_F`.
#[derive(Clone, Debug)]
pub struct MaskSync {
    mask: Option<Mask>,
    /// `(t_ns of frame j, F_j)`: the flow from frame j-1 to frame j.
    flows: VecDeque<(u64, SharedFlow)>,
    capacity: usize,
    synchronise: bool,
}

impl MaskSync {
    /// A stream keeping the flow of the last `capacity` frames. With
    /// `synchronise` false, delayed masks are used as they arrive and never
    /// propagated (the "w/o segm. sync." ablation).
    pub fn new(capacity: usize, synchronise: bool) -> MaskSync {
        MaskSync { mask: None, flows: VecDeque::new(), capacity: capacity.max(1), synchronise }
    }

    /// The current mask `M_t`.
    pub fn mask(&self) -> Option<&Mask> {
        self.mask.as_ref()
    }

    /// Frame `t_ns` with its flow `F_t` (from the previous frame), and maybe a
    /// delayed mask for frame `k_ns <= t_ns`. Updates `M_t` by (5.2) or (5.3).
    pub fn on_frame(
        &mut self,
        t_ns: u64,
        flow: Option<SharedFlow>,
        delayed: Option<(u64, Mask)>,
    ) -> DelayedMaskUse {
        if let Some(f) = &flow {
            self.flows.push_back((t_ns, f.clone()));
            while self.flows.len() > self.capacity {
                self.flows.pop_front();
            }
        }
        let dims = self.mask.as_ref().map(|m| (m.width(), m.height()));
        let offered = delayed.is_some();
        let usable =
            delayed.filter(|(_, m)| !m.is_empty() && dims.is_none_or(|d| d == (m.width(), m.height())));
        let Some((k_ns, delayed_mask)) = usable else {
            // (5.2): no new mask, propagate the stream.
            if self.synchronise
                && let (Some(m), Some(f)) = (&self.mask, &flow)
            {
                self.mask = Some(propagate(m, f));
            }
            return if offered { DelayedMaskUse::Unusable } else { DelayedMaskUse::None };
        };
        if !self.synchronise || k_ns >= t_ns {
            self.mask = Some(delayed_mask);
            return DelayedMaskUse::AsIs;
        }
        // (5.3): carry M^d_k through F_{k+1}, ..., F_t.
        let oldest = self.flows.front().map(|(t, _)| *t);
        let covered = oldest.is_some_and(|t| t <= k_ns.saturating_add(1)) || self.flows.len() < self.capacity;
        if !covered {
            if let (Some(m), Some(f)) = (&self.mask, &flow) {
                self.mask = Some(propagate(m, f));
            }
            return DelayedMaskUse::TooOld;
        }
        let mut m = delayed_mask;
        let mut applied = 0;
        for (_, f) in self.flows.iter().filter(|(t, _)| *t > k_ns && *t <= t_ns) {
            m = propagate(&m, f);
            applied += 1;
        }
        self.mask = Some(m);
        DelayedMaskUse::Synchronised { flows: applied }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::roft::image::{FlowField, PixelBox};
    use std::sync::Arc;

    fn uniform_flow(w: u32, h: u32, du: f32, dv: f32) -> SharedFlow {
        let region = PixelBox { u0: 0, v0: 0, u1: w, v1: h };
        Arc::new(FlowField { region, flow_px: vec![[du, dv]; (w * h) as usize] })
    }

    fn square(w: u32, h: u32, u0: u32, v0: u32, size: u32) -> Mask {
        let mut m = Mask::empty(w, h);
        for v in v0..v0 + size {
            for u in u0..u0 + size {
                m.insert(u, v);
            }
        }
        m
    }

    #[test]
    fn a_mask_follows_a_uniform_flow() {
        let m = square(40, 30, 5, 5, 4);
        let moved = propagate(&m, &uniform_flow(40, 30, 2.4, -1.6));
        assert_eq!(moved, square(40, 30, 7, 3, 4));
        // Pixels leaving the image are dropped.
        let out = propagate(&m, &uniform_flow(40, 30, -7.0, 0.0));
        assert_eq!(out.count(), 4 * 2);
    }

    #[test]
    fn a_delayed_mask_is_carried_to_the_current_frame() {
        let (w, h) = (60, 40);
        let mut sync = MaskSync::new(10, true);
        // Frame 0: the first mask; frames 1..=6 move 2 px right each.
        assert_eq!(sync.on_frame(0, None, Some((0, square(w, h, 10, 10, 5)))), DelayedMaskUse::AsIs);
        for k in 1..=6u64 {
            sync.on_frame(k, Some(uniform_flow(w, h, 2.0, 0.0)), None);
        }
        assert_eq!(sync.mask(), Some(&square(w, h, 22, 10, 5)));
        // At frame 7 the network delivers the mask of frame 1 (x = 12): it is
        // propagated through F_2..F_7 (6 flows, 12 px).
        let used = sync.on_frame(7, Some(uniform_flow(w, h, 2.0, 0.0)), Some((1, square(w, h, 12, 10, 5))));
        assert_eq!(used, DelayedMaskUse::Synchronised { flows: 6 });
        assert_eq!(sync.mask(), Some(&square(w, h, 24, 10, 5)));
    }

    #[test]
    fn without_synchronisation_masks_are_used_as_they_arrive() {
        let (w, h) = (60, 40);
        let mut sync = MaskSync::new(10, false);
        sync.on_frame(0, None, Some((0, square(w, h, 10, 10, 5))));
        sync.on_frame(1, Some(uniform_flow(w, h, 2.0, 0.0)), None);
        assert_eq!(sync.mask(), Some(&square(w, h, 10, 10, 5)));
        let used = sync.on_frame(2, Some(uniform_flow(w, h, 2.0, 0.0)), Some((1, square(w, h, 12, 10, 5))));
        assert_eq!(used, DelayedMaskUse::AsIs);
        assert_eq!(sync.mask(), Some(&square(w, h, 12, 10, 5)));
    }

    #[test]
    fn empty_or_old_masks_are_not_used() {
        let (w, h) = (60, 40);
        let mut sync = MaskSync::new(3, true);
        sync.on_frame(0, None, Some((0, square(w, h, 10, 10, 5))));
        assert_eq!(sync.on_frame(1, None, Some((1, Mask::empty(w, h)))), DelayedMaskUse::Unusable);
        for k in 2..=8u64 {
            sync.on_frame(k, Some(uniform_flow(w, h, 1.0, 0.0)), None);
        }
        let used = sync.on_frame(9, Some(uniform_flow(w, h, 1.0, 0.0)), Some((2, square(w, h, 0, 0, 3))));
        assert_eq!(used, DelayedMaskUse::TooOld);
    }
}
