//! The whole algorithm in one process: segmentation then localization. `gema2 locate` and the
//! pipeline's stages run this same code, so offline results equal what the processes publish.

use crate::localizer::{Localization, Localizer, LocalizerConfig};
use crate::model::MapModel;
use crate::sequential::SequentialConfig;
use laser::ScanView;
use map::MapCornerConfig;
use segment::{LineVisibilitySegmenter, Segmentation, Segmenter, SegmenterConfig};
use std::sync::Arc;

/// The configuration of both stages, which every process shares (the localize process rebuilds
/// samples from the scan with the segmenter's error model).
#[derive(Clone, Copy, Debug, Default)]
pub struct Gema2Config {
    pub segmenter: SegmenterConfig,
    pub localizer: LocalizerConfig,
    /// Map corners, which the localizer matches scan corners against.
    pub map_corners: MapCornerConfig,
    /// The sequential localizer's (`gema2 locate --sequential`, the stage's `--impl
    /// sequential`): chiefly how far the robot's odometry may be off.
    pub sequential: SequentialConfig,
}

pub struct Gema2 {
    pub segmenter: Box<dyn Segmenter>,
    pub localizer: Localizer,
}

impl Gema2 {
    /// The paper's segmentation (line visibility) and this project's localizer.
    pub fn new(model: Arc<MapModel>, segmenter: SegmenterConfig, localizer: LocalizerConfig) -> Self {
        Gema2 {
            segmenter: Box::new(LineVisibilitySegmenter::new(segmenter)),
            localizer: Localizer::new(model, localizer),
        }
    }

    /// Segments and localizes one scan.
    pub fn process(&mut self, scan: &ScanView<'_>) -> (&Segmentation, &Localization) {
        let seg = self.segmenter.segment(scan);
        let loc = self.localizer.locate(scan, seg);
        (seg, loc)
    }
}
