//! `synth`: training images with exact ground truth.

use super::common::{load_family, output_folder, progress_bar, write_output};
use super::error::{bad_input, failure, Classify, Result};
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    /// Number of images [range: 1..=1000000].
    #[arg(short = 'n', long, default_value_t = 32,
          value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub count: u64,
    /// quad: stage-1 scenes (320×320); camera: 1280×960 at 98° with the pose; patch: stage-2
    /// patches (128×128).
    #[arg(long, value_enum, default_value_t = SynthMode::Quad)]
    pub mode: SynthMode,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Image width in px [range: 16..=8192] [default: the mode's].
    #[arg(long, value_parser = image_side())]
    pub width: Option<u32>,
    /// Image height in px [range: 16..=8192] [default: the mode's].
    #[arg(long, value_parser = image_side())]
    pub height: Option<u32>,
    /// Exact renderings: no noise, blur, lighting or distortion.
    #[arg(long)]
    pub no_augment: bool,
    /// Markers per image, N or MIN-MAX (0 gives marker-free scenes, for false-positive tests)
    /// [range: 0..=64] [default: 1-3; patch mode: 1].
    #[arg(long, value_parser = marker_count)]
    pub markers: Option<[u32; 2]>,
    /// Output folder (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// The image sizes synthesis accepts (`SynthError::ImageSize`), checked before the output folder
/// is made.
fn image_side() -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::<u32>::new().range(16..=8192)
}

fn marker_count(text: &str) -> std::result::Result<[u32; 2], String> {
    let number = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|&n| n <= 64)
            .ok_or_else(|| format!("{t:?} is not a marker count in 0..=64"))
    };
    let range = match text.split_once('-') {
        Some((lo, hi)) => [number(lo)?, number(hi)?],
        None => [number(text)?; 2],
    };
    if range[0] > range[1] {
        return Err(format!("{text:?}: the minimum is above the maximum"));
    }
    Ok(range)
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SynthMode {
    Quad,
    Camera,
    Patch,
}

impl SynthArgs {
    pub fn run(self) -> Result<()> {
        use rayon::prelude::*;
        use tagsmith::synth::{self, contact, Mode, SynthConfig};
        let family = load_family(&self.family)?;
        let mode = match self.mode {
            SynthMode::Quad => Mode::Quad,
            SynthMode::Camera => Mode::Camera,
            SynthMode::Patch => Mode::Patch,
        };
        let mut config = SynthConfig::new(mode);
        config.width = self.width.unwrap_or(config.width);
        config.height = self.height.unwrap_or(config.height);
        if self.no_augment {
            config.augment = synth::augment::AugmentRanges::none();
        }
        if let Some(range) = self.markers {
            if mode == Mode::Patch && range != [1, 1] {
                return Err(bad_input!("--markers: a patch holds exactly one marker"));
            }
            config.markers = range;
        }
        output_folder(&self.output, "--output")?;
        std::fs::create_dir_all(&self.output)
            .with_context(|| format!("cannot create {}", self.output.display()))
            .failure()?;
        let bar = progress_bar(
            self.count,
            "{bar:30} {pos}/{len} images  [{elapsed_precise}, ETA {eta}]",
        );
        // Every image has its own seed, so the set is the same whatever the number of threads.
        let kept: Vec<_> = (0..self.count)
            .into_par_iter()
            .map(|i| -> Result<_> {
                let sample = synth::synthesize(&family, &config, synth::image_seed(self.seed, i))?;
                let stem = format!("{i:06}");
                let png = tagsmith::image::encode_png(&sample.image).failure()?;
                write_output(&self.output.join(format!("{stem}.png")), &png)?;
                let json =
                    serde_json::to_string_pretty(&sample.truth).expect("ground truth serialises");
                write_output(&self.output.join(format!("{stem}.json")), json.as_bytes())?;
                bar.inc(1);
                Ok((i < 36).then_some((sample.image, sample.truth)))
            })
            .collect::<Result<Vec<_>>>()?;
        bar.finish_and_clear();
        let thumbs: Vec<_> = kept.into_iter().flatten().collect();
        let sheet = contact::contact_sheet(&thumbs, 6, 256)
            .ok_or_else(|| failure!("cannot draw the contact sheet"))?;
        let png = sheet.encode_png().failure()?;
        write_output(&self.output.join("contact.png"), &png)?;
        println!(
            "wrote {} images ({}×{}, {} mode, seed {}) with ground truth to {}, and contact.png",
            self.count,
            config.width,
            config.height,
            format!("{mode:?}").to_lowercase(),
            self.seed,
            self.output.display()
        );
        Ok(())
    }
}
