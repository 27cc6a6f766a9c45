//! How the detector runs, as a user sets it: one type for `tagsmith detect`, `tagsmith
//! detect-set` (a flattened clap group on the desktop) and the studio's Detect panel, and the one
//! place that turns it into the library's [`DetectorOptions`].

use tagsmith::detect::refine::RefineMode;
use tagsmith::detect::stage1::group::GroupOptions;
use tagsmith::detect::stage2::ReadOptions;
use tagsmith::detect::verifier::VerifierParams;
use tagsmith::detect::DetectorOptions;

#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(not(target_arch = "wasm32"), derive(clap::Args))]
pub struct DetectorSettings {
    /// Stage-2 passes (the second starts from the first's keypoints, also when the first decodes
    /// nothing, a read then kept only if `--refine full` aligns it) [range: 1..=10].
    #[cfg_attr(
        not(target_arch = "wasm32"),
        arg(long, default_value_t = 2, value_parser = parsers::iterations())
    )]
    pub iterations: usize,
    /// After stage 2: none (its keypoints as they are), keypoints (one homography through all
    /// of them), full (that homography aligned with the image against the family's rendering of
    /// the decoded ID).
    #[cfg_attr(
        not(target_arch = "wasm32"),
        arg(long, default_value = "full", value_parser = parsers::refine_mode())
    )]
    pub refine: RefineMode,
    /// Stage 1's corner confidence threshold (lower finds more, costs more stage-2 reads)
    /// [range: (0, 1)].
    #[cfg_attr(
        not(target_arch = "wasm32"),
        arg(long, default_value_t = GroupOptions::default().corner, value_parser = parsers::unit_interval())
    )]
    pub corner_threshold: f32,
    /// Stage 1 also looks at the image enlarged twice: finds markers down to about 10 px wide
    /// (from about 20 px), at four times stage 1's cost on the full-size image.
    #[cfg_attr(not(target_arch = "wasm32"), arg(long))]
    pub upsample: bool,
    /// Skip the searches for the steep views the network's grouping misses: stage 1's weaker
    /// corners joined where the image shows a quad's sides, quads traced around dark blobs where
    /// the network sees a marker (its mask or its corners), and the network's closer look (twice
    /// the size) and stretched look (four times across a corner's direction) around its strong
    /// corners that no read accounts for (on the real photographs of BENCHMARKS.md, "Real
    /// photographs", a third to a half of the time).
    #[cfg_attr(not(target_arch = "wasm32"), arg(long))]
    pub no_outline: bool,
    /// Read only through stage 2's network: no cell reads straight off the image for the ROIs
    /// it reads nothing from, nor for the traced quads past its reads, and no second network
    /// read from the marker frame the cells fitted (black-and-white grid families).
    #[cfg_attr(not(target_arch = "wasm32"), arg(long))]
    pub no_cell_reads: bool,
    /// Skip the edge fits: quads of four of stage 1's corners whose sides the image's edges
    /// confirm, and second reads of the ROIs nothing read once their four sides are fitted to
    /// those edges (a far steep sliver reads only from corners within about a pixel; a few ms
    /// on images with markers left unread or clutter).
    #[cfg_attr(not(target_arch = "wasm32"), arg(long))]
    pub no_edge_fits: bool,
    /// The learned verifier's threshold: candidate quads it scores below this (the probability
    /// that they frame a marker) get no stage-2 pass; 0 sends every quad to stage 2 [range:
    /// 0..1].
    #[cfg_attr(
        not(target_arch = "wasm32"),
        arg(long, default_value_t = VerifierParams::default().min_score, value_parser = parsers::share())
    )]
    #[serde(default = "default_verifier_threshold")]
    pub verifier_threshold: f32,
}

fn default_verifier_threshold() -> f32 {
    VerifierParams::default().min_score
}

impl Default for DetectorSettings {
    fn default() -> Self {
        Self {
            iterations: ReadOptions::default().iterations,
            refine: ReadOptions::default().refine,
            corner_threshold: GroupOptions::default().corner,
            upsample: false,
            no_outline: false,
            no_cell_reads: false,
            no_edge_fits: false,
            verifier_threshold: default_verifier_threshold(),
        }
    }
}

impl DetectorSettings {
    /// How stage 2 reads a ROI.
    pub fn read_options(&self) -> ReadOptions {
        ReadOptions {
            iterations: self.iterations,
            refine: self.refine,
            ..ReadOptions::default()
        }
    }

    /// Sets what these settings cover in `options`, leaving the rest as it is.
    pub fn apply(&self, options: &mut DetectorOptions) {
        options.read = self.read_options();
        options.propose.group.corner = self.corner_threshold;
        options.propose.upsample = self.upsample;
        options.propose.set_image_searches(!self.no_outline);
        options.cell_reads = !self.no_cell_reads;
        options.edge_fits = !self.no_edge_fits;
        options.verifier.min_score = self.verifier_threshold;
    }
}

#[cfg(not(target_arch = "wasm32"))]
mod parsers {
    use super::RefineMode;
    use clap::builder::TypedValueParser;

    pub fn iterations() -> clap::builder::RangedU64ValueParser<usize> {
        clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10)
    }

    pub fn refine_mode() -> impl TypedValueParser<Value = RefineMode> {
        clap::builder::PossibleValuesParser::new(RefineMode::NAMES)
            .map(|s| s.parse::<RefineMode>().expect("one of the names"))
    }

    pub fn share() -> impl TypedValueParser<Value = f32> {
        clap::builder::StringValueParser::new().try_map(|s| {
            let v: f32 = s.parse().map_err(|e| format!("{e}"))?;
            if (0.0..1.0).contains(&v) {
                Ok(v)
            } else {
                Err(format!("{v} is not in [0, 1)"))
            }
        })
    }

    pub fn unit_interval() -> impl TypedValueParser<Value = f32> {
        clap::builder::StringValueParser::new().try_map(|s| {
            let v: f32 = s.parse().map_err(|e| format!("{e}"))?;
            if v > 0.0 && v < 1.0 {
                Ok(v)
            } else {
                Err(format!("{v} is not in (0, 1)"))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_the_libraries_defaults() {
        let mut options = DetectorOptions::default();
        DetectorSettings::default().apply(&mut options);
        assert_eq!(options, DetectorOptions::default());
    }

    #[test]
    fn each_setting_reaches_the_detector() {
        let settings = DetectorSettings {
            iterations: 1,
            refine: RefineMode::Keypoints,
            corner_threshold: 0.5,
            upsample: true,
            no_outline: true,
            no_cell_reads: true,
            no_edge_fits: true,
            verifier_threshold: 0.0,
        };
        let mut options = DetectorOptions::default();
        settings.apply(&mut options);
        assert_eq!(options.read.iterations, 1);
        assert_eq!(options.read.refine, RefineMode::Keypoints);
        assert_eq!(options.propose.group.corner, 0.5);
        assert!(options.propose.upsample);
        assert!(!options.propose.image_searches());
        assert!(!options.cell_reads && !options.edge_fits);
        assert_eq!(options.verifier.min_score, 0.0);
    }
}
