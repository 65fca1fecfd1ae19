//! `--noise-model` as a flag: the parsed model and the file it read.

use std::path::PathBuf;

/// `--noise-model`: the model, and the calibration file it read, if any
/// (an input no output may overwrite).
#[derive(Debug, Clone)]
pub struct NoiseModelArg {
    /// The model.
    pub model: layout_opt::noise::NoiseModel,
    /// The calibration file it read, if any.
    pub file: Option<PathBuf>,
}

impl std::str::FromStr for NoiseModelArg {
    type Err = <layout_opt::noise::NoiseModel as std::str::FromStr>::Err;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let model = text.parse()?;
        let file = text
            .split('+')
            .next()
            .and_then(|kind| kind.strip_prefix("calibrated:"))
            .map(PathBuf::from);
        Ok(NoiseModelArg { model, file })
    }
}
