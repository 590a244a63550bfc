//! Denoiser weights on disk: a safetensors file whose metadata carries the format name and version,
//! the architecture, the control normalization and how the weights were trained. Loading checks
//! all of them and every tensor's name and shape against the architecture, and says what differs.

use std::collections::HashMap;

use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use serde::{Deserialize, Serialize};

use crate::denoiser::{Denoiser, DenoiserConfig};
use crate::guidance::normalized::ControlNormalization;

/// Format name in the metadata.
pub const FORMAT: &str = "v2t-denoiser";
/// Format version written and read.
pub const VERSION: u32 = 1;

/// How a weights file was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainingRecord {
    /// The command line that made it.
    pub command: String,
    /// Where the data came from (`synthetic corpus, seed 1, 1000 episodes, proving_ground`, a file).
    pub data: String,
    /// Whether the data is synthetic.
    pub synthetic: bool,
    /// Training windows and held-out windows.
    pub train_windows: usize,
    /// Held-out windows.
    pub heldout_windows: usize,
    /// Optimizer steps.
    pub steps: usize,
    /// Batch size.
    pub batch: usize,
    /// Seed of the training run.
    pub seed: u64,
    /// Final held-out loss (noise-prediction MSE).
    pub heldout_loss: f64,
}

/// The per-channel control normalization, as stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NormalizationRecord {
    /// `μ_a`, m/s².
    pub accel_mean_mps2: f64,
    /// `σ_a`, m/s².
    pub accel_scale_mps2: f64,
    /// `μ_ω`, rad/s.
    pub yaw_rate_mean_radps: f64,
    /// `σ_ω`, rad/s.
    pub yaw_rate_scale_radps: f64,
}

impl From<ControlNormalization> for NormalizationRecord {
    fn from(n: ControlNormalization) -> Self {
        Self {
            accel_mean_mps2: n.accel_mean_mps2,
            accel_scale_mps2: n.accel_scale_mps2,
            yaw_rate_mean_radps: n.yaw_rate_mean_radps,
            yaw_rate_scale_radps: n.yaw_rate_scale_radps,
        }
    }
}

impl From<NormalizationRecord> for ControlNormalization {
    fn from(n: NormalizationRecord) -> Self {
        Self {
            accel_mean_mps2: n.accel_mean_mps2,
            accel_scale_mps2: n.accel_scale_mps2,
            yaw_rate_mean_radps: n.yaw_rate_mean_radps,
            yaw_rate_scale_radps: n.yaw_rate_scale_radps,
        }
    }
}

/// Everything but the tensors.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelMeta {
    /// Architecture.
    pub config: DenoiserConfig,
    /// Control normalization the network was trained with.
    pub normalization: ControlNormalization,
    /// Provenance.
    pub training: TrainingRecord,
}

/// A loaded model: the network and its metadata.
#[derive(Debug)]
pub struct Model {
    /// The network.
    pub denoiser: Denoiser,
    /// Its metadata.
    pub meta: ModelMeta,
}

/// What can go wrong with a weights file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WeightsError {
    /// The file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        message: String,
    },
    /// Not a safetensors file.
    #[error("not a safetensors file: {0}")]
    NotSafetensors(String),
    /// A safetensors file of something else.
    #[error("weights format `{0}`, expected `{FORMAT}`")]
    Format(String),
    /// A version this reader does not know.
    #[error("weights version {found}, this build reads version {VERSION}")]
    Version {
        /// The file's version.
        found: String,
    },
    /// A metadata entry is missing or malformed.
    #[error("weights metadata `{field}`: {message}")]
    Metadata {
        /// Which entry.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A tensor the architecture needs is not in the file.
    #[error("weights: tensor `{0}` missing for this architecture")]
    Missing(String),
    /// A tensor the architecture does not have.
    #[error("weights: unexpected tensor `{0}` (the file is of another architecture)")]
    Unexpected(String),
    /// A tensor of the wrong shape.
    #[error("weights: tensor `{name}` has shape {found:?}, the architecture needs {expected:?}")]
    Shape {
        /// The tensor.
        name: String,
        /// Needed.
        expected: Vec<usize>,
        /// In the file.
        found: Vec<usize>,
    },
    /// A tensor with NaN or infinite entries.
    #[error("weights: tensor `{0}` has non-finite entries")]
    NonFinite(String),
    /// The tensor library failed.
    #[error("weights: {0}")]
    Tensor(String),
    /// A weights file that is not usable, and why.
    #[error("{path}: {source}")]
    File {
        /// The file.
        path: String,
        /// Why.
        source: Box<WeightsError>,
    },
}

fn tensor_err(e: candle_core::Error) -> WeightsError {
    WeightsError::Tensor(e.to_string())
}

/// The bytes of a weights file for the variables of `varmap`.
pub fn to_bytes(varmap: &VarMap, meta: &ModelMeta) -> Result<Vec<u8>, WeightsError> {
    let json = |field: &'static str, v: Result<String, serde_json::Error>| {
        v.map_err(|e| WeightsError::Metadata { field, message: e.to_string() })
    };
    let metadata: HashMap<String, String> = [
        ("format".to_owned(), FORMAT.to_owned()),
        ("version".to_owned(), VERSION.to_string()),
        ("config".to_owned(), json("config", serde_json::to_string(&meta.config))?),
        (
            "normalization".to_owned(),
            json("normalization", serde_json::to_string(&NormalizationRecord::from(meta.normalization)))?,
        ),
        ("training".to_owned(), json("training", serde_json::to_string(&meta.training))?),
    ]
    .into_iter()
    .collect();
    let data = varmap.data().lock().map_err(|_| WeightsError::Tensor("variable map lock poisoned".into()))?;
    let mut named: Vec<(String, Tensor)> = data.iter().map(|(k, v)| (k.clone(), v.as_tensor().clone())).collect();
    drop(data);
    named.sort_by(|a, b| a.0.cmp(&b.0));
    safetensors::tensor::serialize(named.iter().map(|(k, v)| (k.as_str(), v)), &Some(metadata))
        .map_err(|e| WeightsError::Tensor(e.to_string()))
}

/// Writes the weights of `varmap` to `path`.
pub fn save(varmap: &VarMap, meta: &ModelMeta, path: &std::path::Path) -> Result<(), WeightsError> {
    let bytes = to_bytes(varmap, meta)?;
    std::fs::write(path, bytes)
        .map_err(|e| WeightsError::Io { path: path.display().to_string(), message: e.to_string() })
}

/// The metadata of a weights file (format and version checked first).
pub fn read_meta(bytes: &[u8]) -> Result<ModelMeta, WeightsError> {
    let (_, header) =
        safetensors::SafeTensors::read_metadata(bytes).map_err(|e| WeightsError::NotSafetensors(e.to_string()))?;
    let empty = HashMap::new();
    let md = header.metadata().as_ref().unwrap_or(&empty);
    let format = md.get("format").cloned().unwrap_or_default();
    if format != FORMAT {
        return Err(WeightsError::Format(format));
    }
    let version = md.get("version").cloned().unwrap_or_default();
    if version != VERSION.to_string() {
        return Err(WeightsError::Version { found: version });
    }
    fn field<T: serde::de::DeserializeOwned>(
        md: &HashMap<String, String>,
        field: &'static str,
    ) -> Result<T, WeightsError> {
        let text = md.get(field).ok_or(WeightsError::Metadata { field, message: "missing".into() })?;
        serde_json::from_str(text).map_err(|e| WeightsError::Metadata { field, message: e.to_string() })
    }
    let config: DenoiserConfig = field(md, "config")?;
    config.check().map_err(|e| WeightsError::Metadata { field: "config", message: e.to_string() })?;
    let normalization: NormalizationRecord = field(md, "normalization")?;
    let normalization = ControlNormalization::from(normalization);
    normalization.checked().map_err(|e| WeightsError::Metadata { field: "normalization", message: e.to_string() })?;
    let training: TrainingRecord = field(md, "training")?;
    Ok(ModelMeta { config, normalization, training })
}

/// A model from the bytes of a weights file.
pub fn from_bytes(bytes: &[u8]) -> Result<Model, WeightsError> {
    from_bytes_with_variables(bytes).map(|(model, _)| model)
}

/// A model from the bytes of a weights file, with the variables that hold its weights (to train
/// on from there).
pub fn from_bytes_with_variables(bytes: &[u8]) -> Result<(Model, VarMap), WeightsError> {
    let meta = read_meta(bytes)?;
    let device = Device::Cpu;
    let loaded = candle_core::safetensors::load_buffer(bytes, &device).map_err(tensor_err)?;
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &device);
    let denoiser = Denoiser::new(meta.config, vb).map_err(tensor_err)?;
    {
        let data = varmap.data().lock().map_err(|_| WeightsError::Tensor("variable map lock poisoned".into()))?;
        let mut names: Vec<&String> = data.keys().collect();
        names.sort();
        for name in names {
            let var = data.get(name).ok_or_else(|| WeightsError::Missing(name.clone()))?;
            let t = loaded.get(name).ok_or_else(|| WeightsError::Missing(name.clone()))?;
            let expected = var.as_tensor().dims().to_vec();
            if t.dims() != expected.as_slice() {
                return Err(WeightsError::Shape { name: name.clone(), expected, found: t.dims().to_vec() });
            }
            let t = t.to_dtype(DType::F32).map_err(tensor_err)?;
            let finite =
                t.flatten_all().and_then(|f| f.to_vec1::<f32>()).map_err(tensor_err)?.iter().all(|v| v.is_finite());
            if !finite {
                return Err(WeightsError::NonFinite(name.clone()));
            }
            var.set(&t).map_err(tensor_err)?;
        }
        let mut extra: Vec<&String> = loaded.keys().filter(|k| !data.contains_key(*k)).collect();
        extra.sort();
        if let Some(name) = extra.first() {
            return Err(WeightsError::Unexpected((*name).clone()));
        }
    }
    Ok((Model { denoiser, meta }, varmap))
}

/// A model from a weights file.
pub fn load(path: &std::path::Path) -> Result<Model, WeightsError> {
    let bytes = v2t_files::bounds::read_bytes_within(path, v2t_files::bounds::WEIGHTS)
        .map_err(|e| WeightsError::Io { path: path.display().to_string(), message: e.to_string() })?;
    from_bytes(&bytes).map_err(|e| WeightsError::File { path: path.display().to_string(), source: Box::new(e) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> (VarMap, ModelMeta) {
        let config =
            DenoiserConfig { slots: 2, steps: 8, patch: 2, hidden: 8, blocks: 1, embed: 8, diffusion_steps: 10 };
        let varmap = VarMap::new();
        Denoiser::new(config, VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu)).unwrap();
        let meta = ModelMeta {
            config,
            normalization: ControlNormalization::default(),
            training: TrainingRecord {
                command: "test".into(),
                data: "none".into(),
                synthetic: true,
                train_windows: 0,
                heldout_windows: 0,
                steps: 0,
                batch: 1,
                seed: 0,
                heldout_loss: 1.0,
            },
        };
        (varmap, meta)
    }

    /// The bytes of a file with metadata entry `key` replaced (tensors kept).
    fn with_metadata(varmap: &VarMap, meta: &ModelMeta, key: &str, value: &str) -> Vec<u8> {
        let bytes = to_bytes(varmap, meta).unwrap();
        let (_, header) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
        let mut md = header.metadata().clone().unwrap();
        md.insert(key.to_owned(), value.to_owned());
        let loaded = candle_core::safetensors::load_buffer(&bytes, &Device::Cpu).unwrap();
        let mut named: Vec<(String, Tensor)> = loaded.into_iter().collect();
        named.sort_by(|a, b| a.0.cmp(&b.0));
        safetensors::tensor::serialize(named.iter().map(|(k, v)| (k.as_str(), v)), &Some(md)).unwrap()
    }

    #[test]
    fn round_trip_keeps_weights_and_metadata() {
        let (varmap, meta) = tiny();
        let bytes = to_bytes(&varmap, &meta).unwrap();
        let model = from_bytes(&bytes).unwrap();
        assert_eq!(model.meta, meta);
        let z = Tensor::ones((1, 4, 8), DType::F32, &Device::Cpu).unwrap();
        let cond = Tensor::ones((1, meta.config.condition_len()), DType::F32, &Device::Cpu).unwrap();
        let time =
            Tensor::ones((1, meta.config.time_channels(), meta.config.patches()), DType::F32, &Device::Cpu).unwrap();
        let fresh = Denoiser::new(meta.config, VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu)).unwrap();
        let a: Vec<f32> = fresh.forward(&z, &[3], &cond, &time).unwrap().flatten_all().unwrap().to_vec1().unwrap();
        let b: Vec<f32> =
            model.denoiser.forward(&z, &[3], &cond, &time).unwrap().flatten_all().unwrap().to_vec1().unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn wrong_files_are_named_errors() {
        let (varmap, meta) = tiny();
        assert!(matches!(from_bytes(b"not a safetensors file"), Err(WeightsError::NotSafetensors(_))));
        let other = with_metadata(&varmap, &meta, "format", "something-else");
        assert_eq!(from_bytes(&other).unwrap_err(), WeightsError::Format("something-else".into()));
        let newer = with_metadata(&varmap, &meta, "version", "2");
        assert!(from_bytes(&newer).unwrap_err().to_string().contains("version 2"));
        // Metadata announcing another architecture than the tensors: a shape error naming the tensor.
        let wider = DenoiserConfig { hidden: 16, ..meta.config };
        let reshaped = with_metadata(&varmap, &meta, "config", &serde_json::to_string(&wider).unwrap());
        assert!(matches!(from_bytes(&reshaped), Err(WeightsError::Shape { .. })), "{:?}", from_bytes(&reshaped).err());
        let bad_config = with_metadata(&varmap, &meta, "config", r#"{"slots": 1}"#);
        assert!(matches!(from_bytes(&bad_config), Err(WeightsError::Metadata { field: "config", .. })));
        let bad_norm = with_metadata(
            &varmap,
            &meta,
            "normalization",
            r#"{"accel_mean_mps2":0,"accel_scale_mps2":0,"yaw_rate_mean_radps":0,"yaw_rate_scale_radps":1}"#,
        );
        assert!(matches!(from_bytes(&bad_norm), Err(WeightsError::Metadata { field: "normalization", .. })));
        // A NaN weight.
        let nan_map = VarMap::new();
        Denoiser::new(meta.config, VarBuilder::from_varmap(&nan_map, DType::F32, &Device::Cpu)).unwrap();
        for v in nan_map.all_vars() {
            v.set(&(v.as_tensor().ones_like().unwrap() * f64::NAN).unwrap()).unwrap();
        }
        assert!(matches!(from_bytes(&to_bytes(&nan_map, &meta).unwrap()), Err(WeightsError::NonFinite(_))));
        assert!(matches!(load(std::path::Path::new("/nonexistent/w.safetensors")), Err(WeightsError::Io { .. })));
    }
}
