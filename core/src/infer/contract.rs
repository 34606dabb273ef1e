//! The model contract: what a grasp network expects and returns, read from
//! the model file's metadata (ONNX `metadata_props`), never hard-coded twice.

use std::borrow::Cow;

use crate::error::{Error, Result};

/// Output channels of a grasp network, per pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Channel {
    /// Grasp quality in [0, 1].
    Quality,
    /// cos(2 phi) of the grasp angle phi.
    Cos2Phi,
    /// sin(2 phi) of the grasp angle phi.
    Sin2Phi,
    /// Gripper opening, divided by `width_scale_m`.
    Width,
}

impl Channel {
    /// The name used in the metadata.
    pub fn name(self) -> &'static str {
        match self {
            Self::Quality => "quality",
            Self::Cos2Phi => "cos2phi",
            Self::Sin2Phi => "sin2phi",
            Self::Width => "width",
        }
    }

    fn parse(name: &str) -> Option<Self> {
        [Self::Quality, Self::Cos2Phi, Self::Sin2Phi, Self::Width]
            .into_iter()
            .find(|c| c.name() == name)
    }
}

/// The one normalisation this crate implements (see `view` for its definition).
pub const NORMALISATION_CUBE_V1: &str = "cube-v1";

/// Input size, pixel size, output layout and provenance of a grasp network.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelContract {
    /// Views are `input_size_px` x `input_size_px`.
    pub input_size_px: usize,
    /// Metric size of a view pixel (m): views are not scale-invariant.
    pub pixel_size_m: f32,
    /// The width channel times this is the opening in metres.
    pub width_scale_m: f32,
    /// Depth normalisation of the input views.
    pub normalisation: String,
    /// Output channel order (NCHW, C = 4).
    pub outputs: [Channel; 4],
    /// Version of the model.
    pub model_version: String,
    /// Version of the training data it was trained on.
    pub data_version: String,
}

/// Metadata keys of the contract.
pub mod keys {
    /// View side in pixels.
    pub const INPUT_SIZE_PX: &str = "mvgrasp.input_size_px";
    /// Metres per view pixel.
    pub const PIXEL_SIZE_M: &str = "mvgrasp.pixel_size_m";
    /// Metres per unit of the width channel.
    pub const WIDTH_SCALE_M: &str = "mvgrasp.width_scale_m";
    /// Input normalisation name.
    pub const NORMALISATION: &str = "mvgrasp.normalisation";
    /// Comma-separated output channel names.
    pub const OUTPUTS: &str = "mvgrasp.outputs";
    /// Model version.
    pub const MODEL_VERSION: &str = "mvgrasp.model_version";
    /// Training data version.
    pub const DATA_VERSION: &str = "mvgrasp.data_version";
}

impl ModelContract {
    /// The contract of the analytic baseline network ([`super::MomentsNet`]):
    /// 96 px views of 2.5 mm (24 cm across), widths in units of 0.2 m.
    pub fn baseline() -> Self {
        Self {
            input_size_px: 96,
            pixel_size_m: 0.0025,
            width_scale_m: 0.2,
            normalisation: NORMALISATION_CUBE_V1.to_owned(),
            outputs: [
                Channel::Quality,
                Channel::Cos2Phi,
                Channel::Sin2Phi,
                Channel::Width,
            ],
            model_version: "moments-baseline-1".to_owned(),
            data_version: "none".to_owned(),
        }
    }

    /// Side of the square a view covers (m).
    pub fn view_extent_m(&self) -> f32 {
        self.input_size_px as f32 * self.pixel_size_m
    }

    /// Index of `channel` in the output tensor.
    pub fn channel_index(&self, channel: Channel) -> usize {
        self.outputs.iter().position(|&c| c == channel).unwrap_or(0)
    }

    /// Reads and validates the contract from metadata (`get(key)`).
    pub fn from_metadata(get: impl Fn(&str) -> Option<String>) -> Result<Self> {
        let need = |key: &'static str| {
            get(key).ok_or(Error::Contract {
                key: Cow::Borrowed(key),
                reason: "missing".to_owned(),
            })
        };
        let bad = |key: &'static str, reason: String| Error::Contract {
            key: Cow::Borrowed(key),
            reason,
        };
        let number = |key: &'static str| -> Result<f64> {
            let raw = need(key)?;
            raw.trim()
                .parse::<f64>()
                .map_err(|e| bad(key, format!("{raw:?} is not a number: {e}")))
        };
        let size = number(keys::INPUT_SIZE_PX)?;
        if !(size.fract() == 0.0 && (8.0..=1024.0).contains(&size)) {
            return Err(bad(
                keys::INPUT_SIZE_PX,
                format!("{size} is not an integer in 8..=1024"),
            ));
        }
        let pixel = number(keys::PIXEL_SIZE_M)?;
        if !(pixel.is_finite() && (1e-4..=0.05).contains(&pixel)) {
            return Err(bad(
                keys::PIXEL_SIZE_M,
                format!("{pixel} m is outside 0.1..50 mm"),
            ));
        }
        let width_scale = number(keys::WIDTH_SCALE_M)?;
        if !(width_scale.is_finite() && width_scale > 0.0 && width_scale <= 2.0) {
            return Err(bad(
                keys::WIDTH_SCALE_M,
                format!("{width_scale} m is outside (0, 2]"),
            ));
        }
        let normalisation = need(keys::NORMALISATION)?;
        if normalisation != NORMALISATION_CUBE_V1 {
            return Err(bad(
                keys::NORMALISATION,
                format!("{normalisation:?} is not supported (this build knows {NORMALISATION_CUBE_V1:?})"),
            ));
        }
        let raw_outputs = need(keys::OUTPUTS)?;
        let parsed: Vec<Option<Channel>> = raw_outputs.split(',').map(|s| Channel::parse(s.trim())).collect();
        let outputs: [Channel; 4] = match parsed.as_slice() {
            [Some(a), Some(b), Some(c), Some(d)] => [*a, *b, *c, *d],
            _ => {
                return Err(bad(
                    keys::OUTPUTS,
                    format!("{raw_outputs:?} must name quality, cos2phi, sin2phi and width once each"),
                ));
            }
        };
        for channel in [
            Channel::Quality,
            Channel::Cos2Phi,
            Channel::Sin2Phi,
            Channel::Width,
        ] {
            if !outputs.contains(&channel) {
                return Err(bad(
                    keys::OUTPUTS,
                    format!("{raw_outputs:?} lacks {}", channel.name()),
                ));
            }
        }
        Ok(Self {
            input_size_px: size as usize,
            pixel_size_m: pixel as f32,
            width_scale_m: width_scale as f32,
            normalisation,
            outputs,
            model_version: need(keys::MODEL_VERSION)?,
            data_version: get(keys::DATA_VERSION).unwrap_or_else(|| "unknown".to_owned()),
        })
    }

    /// The metadata that [`Self::from_metadata`] reads back.
    pub fn to_metadata(&self) -> Vec<(&'static str, String)> {
        vec![
            (keys::INPUT_SIZE_PX, self.input_size_px.to_string()),
            (keys::PIXEL_SIZE_M, self.pixel_size_m.to_string()),
            (keys::WIDTH_SCALE_M, self.width_scale_m.to_string()),
            (keys::NORMALISATION, self.normalisation.clone()),
            (
                keys::OUTPUTS,
                self.outputs
                    .iter()
                    .map(|c| c.name())
                    .collect::<Vec<_>>()
                    .join(","),
            ),
            (keys::MODEL_VERSION, self.model_version.clone()),
            (keys::DATA_VERSION, self.data_version.clone()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;

    #[test]
    fn metadata_round_trip() {
        let mut contract = ModelContract::baseline();
        contract.outputs = [
            Channel::Width,
            Channel::Quality,
            Channel::Sin2Phi,
            Channel::Cos2Phi,
        ];
        let map: HashMap<&str, String> = contract.to_metadata().into_iter().collect();
        let back = ModelContract::from_metadata(|k| map.get(k).cloned()).unwrap();
        assert_eq!(back, contract);
        assert_eq!(back.channel_index(Channel::Quality), 1);
    }

    #[test]
    fn bad_metadata_names_the_key() {
        let base: HashMap<&str, String> = ModelContract::baseline().to_metadata().into_iter().collect();
        for (key, value) in [
            (keys::INPUT_SIZE_PX, Some("96.5")),
            (keys::PIXEL_SIZE_M, Some("abc")),
            (keys::OUTPUTS, Some("quality,quality,sin2phi,width")),
            (keys::NORMALISATION, Some("minmax")),
            (keys::MODEL_VERSION, None),
        ] {
            let mut map = base.clone();
            match value {
                Some(v) => map.insert(key, v.to_owned()),
                None => map.remove(key),
            };
            let err = ModelContract::from_metadata(|k| map.get(k).cloned()).unwrap_err();
            assert!(err.to_string().contains(key), "{key}: {err}");
        }
    }
}
