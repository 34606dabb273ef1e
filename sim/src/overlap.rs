//! How the planner's detections overlap the renderer's labels, counted on
//! the pixels the planner kept as object points (`segmentation_recall` and
//! `why_no_grasp` in `examples/`).

use std::collections::HashMap;

use mvgrasp_core::Segmentation;

use crate::camera::Frame;

/// Pixel counts of one frame's segmentation against its labels; only
/// object labels (>= 2) count.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Overlap {
    /// Kept pixels of each object label, in a detection or not.
    pub of_label: HashMap<u16, usize>,
    /// Object pixels in each detection.
    pub of_detection: Vec<usize>,
    /// Pixels of each (detection, label).
    pub shared: HashMap<(usize, u16), usize>,
}

impl Overlap {
    /// The counts of `seg` (a segmentation of a depth image) on `frame`.
    pub fn new(frame: &Frame, seg: &Segmentation) -> Self {
        let mut detection_of_point = vec![usize::MAX; seg.points.len()];
        for (d, c) in seg.clusters.iter().enumerate() {
            for &i in c {
                detection_of_point[i as usize] = d;
            }
        }
        let mut overlap = Self {
            of_detection: vec![0; seg.clusters.len()],
            ..Self::default()
        };
        for (i, &pixel) in seg.pixels.iter().enumerate() {
            let label = frame.labels[pixel as usize];
            if label < 2 {
                continue;
            }
            *overlap.of_label.entry(label).or_default() += 1;
            let d = detection_of_point[i];
            if d != usize::MAX {
                overlap.of_detection[d] += 1;
                *overlap.shared.entry((d, label)).or_default() += 1;
            }
        }
        overlap
    }

    /// `(detection, pixels)` of each detection holding some of `label`.
    pub fn shares(&self, label: u16) -> Vec<(usize, usize)> {
        self.shared
            .iter()
            .filter(|((_, l), _)| *l == label)
            .map(|(&(d, _), &k)| (d, k))
            .collect()
    }

    /// Whether two or more detections each hold at least 20% of `label`'s
    /// pixels.
    pub fn is_split(&self, label: u16) -> bool {
        let n = self.of_label.get(&label).copied().unwrap_or(0);
        self.shares(label).iter().filter(|&&(_, k)| k * 5 >= n).count() >= 2
    }

    /// Detections in which two or more objects each hold at least 20% of
    /// the pixels.
    pub fn merged(&self) -> usize {
        (0..self.of_detection.len())
            .filter(|&d| {
                self.shared
                    .iter()
                    .filter(|((e, _), k)| *e == d && **k * 5 >= self.of_detection[d])
                    .count()
                    >= 2
            })
            .count()
    }
}
