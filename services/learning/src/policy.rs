//! The exported policy and its pure-Rust runtime: what a robot or a validation worker embeds.
//! No libtorch: weights come from a safetensors file, the layout and scaling from a JSON file
//! beside it, and a forward pass is a few hundred lines of arithmetic away from tch's result
//! (within 1e-5; a test checks).
//!
//! Files of an exported policy directory:
//! - `policy.safetensors`: `layers.{i}.weight` (`[out, in]`, f32) and `layers.{i}.bias` (`[out]`)
//!   for each linear layer of the actor, input first;
//! - `policy.json`: [`PolicyMetadata`].

use std::path::Path;

use serde::{Deserialize, Serialize};
use sim::{Action, Observation};

use crate::observation::{ACTION_DIM, Residual, Scaling};

/// Name of the weights file in a policy directory.
pub const WEIGHTS_FILE: &str = "policy.safetensors";
/// Name of the metadata file in a policy directory.
pub const METADATA_FILE: &str = "policy.json";
/// The `format` field of [`PolicyMetadata`].
pub const FORMAT: &str = "mentalsim-td3-actor";

/// What a policy directory says about its network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PolicyMetadata {
    /// Always [`FORMAT`].
    pub format: String,
    /// Format version (1).
    pub version: u32,
    /// Input and output scaling; the input layout is `observation_layout`.
    pub scaling: Scaling,
    /// Names of the network inputs in order.
    pub observation_layout: Vec<String>,
    /// Widths of the hidden layers (ReLU).
    pub hidden: Vec<usize>,
    /// Activation of each output: `sigmoid` for the linear speed, `tanh` for the angular one.
    pub output_activations: Vec<String>,
    /// How the policy was trained (free-form: configuration, counters, last evaluation).
    #[serde(default)]
    pub training: serde_json::Value,
    /// When present, the network learned a correction to this base (the classical follower
    /// steering at the goal): its raw outputs are added to the base's pre-activations before
    /// the output activations ([`Residual::preactivation`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual: Option<Residual>,
}

impl PolicyMetadata {
    /// Metadata for an actor with `hidden` layers and `scaling`.
    pub fn new(scaling: Scaling, hidden: Vec<usize>, training: serde_json::Value) -> Self {
        let mut layout: Vec<String> = (0..scaling.beams)
            .map(|i| format!("range[{i}] / range_horizon_m (rightmost beam first)"))
            .collect();
        layout.extend(scaling.layout.names().iter().map(|n| (*n).to_owned()));
        Self {
            format: FORMAT.into(),
            version: 1,
            scaling,
            observation_layout: layout,
            hidden,
            output_activations: vec!["sigmoid".into(), "tanh".into()],
            training,
            residual: None,
        }
    }
}

/// Why a policy could not be loaded or used.
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The metadata is not what this runtime understands.
    #[error("policy metadata: {0}")]
    Metadata(String),
    /// The weights do not fit the metadata.
    #[error("policy weights: {0}")]
    Weights(String),
    /// An observation does not fit the policy.
    #[error("observation: {0}")]
    Observation(String),
}

/// One linear layer, row-major weights.
#[derive(Clone, Debug, PartialEq)]
struct Dense {
    inputs: usize,
    outputs: usize,
    weight: Vec<f32>,
    bias: Vec<f32>,
}

impl Dense {
    fn forward(&self, x: &[f32], y: &mut [f32]) {
        for ((out, row), b) in y
            .iter_mut()
            .zip(self.weight.chunks_exact(self.inputs))
            .zip(&self.bias)
        {
            *out = dot(row, x) + b;
        }
    }
}

/// A dot product written so the compiler vectorises it (eight independent sums). A multiply
/// and an add, not `mul_add`: without the `fma` target feature (the portable build) `mul_add`
/// is a call into libm per element, several times slower than the whole vectorised loop.
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// A trained actor that runs without libtorch.
#[derive(Clone, Debug)]
pub struct Policy {
    meta: PolicyMetadata,
    layers: Vec<Dense>,
    widest: usize,
}

/// The weights of one layer as named in the safetensors file.
pub fn weight_name(layer: usize) -> String {
    format!("layers.{layer}.weight")
}

/// The bias of one layer as named in the safetensors file.
pub fn bias_name(layer: usize) -> String {
    format!("layers.{layer}.bias")
}

impl Policy {
    /// Loads `policy.safetensors` and `policy.json` from `dir`.
    pub fn load(dir: &Path) -> Result<Policy, PolicyError> {
        let read = |name: &str| {
            let path = dir.join(name);
            std::fs::read(&path).map_err(|source| PolicyError::Io {
                path: path.display().to_string(),
                source,
            })
        };
        let meta = read(METADATA_FILE)?;
        let weights = read(WEIGHTS_FILE)?;
        Policy::from_bytes(&meta, &weights)
    }

    /// A policy from the two files' contents.
    pub fn from_bytes(metadata_json: &[u8], safetensors: &[u8]) -> Result<Policy, PolicyError> {
        let meta: PolicyMetadata = serde_json::from_slice(metadata_json)
            .map_err(|e| PolicyError::Metadata(e.to_string()))?;
        if meta.format != FORMAT || meta.version != 1 {
            return Err(PolicyError::Metadata(format!(
                "format `{}` version {} is not `{FORMAT}` version 1",
                meta.format, meta.version
            )));
        }
        if meta.output_activations != ["sigmoid", "tanh"] {
            return Err(PolicyError::Metadata(format!(
                "output activations {:?} are not [sigmoid, tanh]",
                meta.output_activations
            )));
        }
        if meta.scaling.beams == 0 || meta.hidden.contains(&0) {
            return Err(PolicyError::Metadata(
                "beam count and hidden widths must be positive".into(),
            ));
        }
        let tensors = safetensors::SafeTensors::deserialize(safetensors)
            .map_err(|e| PolicyError::Weights(format!("{e:?}")))?;
        let mut widths = vec![meta.scaling.input_len()];
        widths.extend(&meta.hidden);
        widths.push(ACTION_DIM);
        let mut layers = Vec::with_capacity(widths.len() - 1);
        for (i, w) in widths.windows(2).enumerate() {
            let (inputs, outputs) = (w[0], w[1]);
            let weight = read_f32(&tensors, &weight_name(i), &[outputs, inputs])?;
            let bias = read_f32(&tensors, &bias_name(i), &[outputs])?;
            layers.push(Dense {
                inputs,
                outputs,
                weight,
                bias,
            });
        }
        if tensors.len() != 2 * layers.len() {
            return Err(PolicyError::Weights(format!(
                "{} tensors for {} layers: the file holds another network",
                tensors.len(),
                layers.len()
            )));
        }
        let widest = widths.iter().copied().max().unwrap_or(ACTION_DIM);
        Ok(Policy {
            meta,
            layers,
            widest,
        })
    }

    /// The metadata.
    pub fn metadata(&self) -> &PolicyMetadata {
        &self.meta
    }

    /// The scaling.
    pub fn scaling(&self) -> &Scaling {
        &self.meta.scaling
    }

    /// The network's output for an already scaled input: linear in [0, 1], angular in [-1, 1].
    pub fn forward(&self, input: &[f32]) -> Result<[f32; ACTION_DIM], PolicyError> {
        if input.len() != self.meta.scaling.input_len() {
            return Err(PolicyError::Observation(format!(
                "{} inputs for a policy that takes {}",
                input.len(),
                self.meta.scaling.input_len()
            )));
        }
        let mut a = vec![0.0f32; self.widest];
        let mut b = vec![0.0f32; self.widest];
        a[..input.len()].copy_from_slice(input);
        let last = self.layers.len() - 1;
        for (i, layer) in self.layers.iter().enumerate() {
            layer.forward(&a[..layer.inputs], &mut b[..layer.outputs]);
            if i < last {
                for v in &mut b[..layer.outputs] {
                    *v = v.max(0.0);
                }
            }
            std::mem::swap(&mut a, &mut b);
        }
        if let Some(residual) = &self.meta.residual {
            let base = residual.preactivation(&self.meta.scaling, input);
            a[0] += base[0];
            a[1] += base[1];
        }
        Ok([sigmoid(a[0]), a[1].tanh()])
    }

    /// The velocity command for an observation.
    pub fn act(&self, obs: &Observation) -> Result<Action, PolicyError> {
        let input = self.meta.scaling.encode(obs).ok_or_else(|| {
            PolicyError::Observation(format!(
                "{} laser ranges for a policy trained on {}",
                obs.ranges.len(),
                self.meta.scaling.beams
            ))
        })?;
        Ok(self.meta.scaling.command(self.forward(&input)?))
    }
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

fn read_f32(
    tensors: &safetensors::SafeTensors<'_>,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f32>, PolicyError> {
    let t = tensors
        .tensor(name)
        .map_err(|_| PolicyError::Weights(format!("missing tensor `{name}`")))?;
    if t.dtype() != safetensors::Dtype::F32 {
        return Err(PolicyError::Weights(format!(
            "`{name}` is {:?}, not F32",
            t.dtype()
        )));
    }
    if t.shape() != shape {
        return Err(PolicyError::Weights(format!(
            "`{name}` has shape {:?}, expected {shape:?}",
            t.shape()
        )));
    }
    Ok(t.data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}

/// Writes a hand-made policy, no training, into `dir`: three hidden units relu(a), relu(-a), 1
/// for the goal bearing a = θ/π (the paper's input layout), linear speed sigmoid(3 − 60 |a|),
/// angular speed tanh(20 a) — it turns towards the goal and drives once facing it. For tests and
/// demonstrations of the runtime and of the plan executor; `training` goes into the metadata.
pub fn write_goal_seeking_policy(
    dir: &Path,
    beams: usize,
    training: serde_json::Value,
) -> Result<PolicyMetadata, PolicyError> {
    let scaling = Scaling {
        beams,
        layout: crate::InputLayout::Paper,
        ..Scaling::default()
    };
    let inputs = scaling.input_len();
    let meta = PolicyMetadata::new(scaling, vec![3], training);
    let mut w0 = vec![0.0f32; 3 * inputs];
    w0[inputs - 1] = 1.0; // relu(a)
    w0[2 * inputs - 1] = -1.0; // relu(-a)
    let layers = [
        (w0, vec![0.0, 0.0, 1.0]),
        (vec![-60.0, -60.0, 3.0, 20.0, -20.0, 0.0], vec![0.0, 0.0]),
    ];
    write_policy(dir, &meta, &layers)?;
    Ok(meta)
}

/// Writes an actor's layers (`(weight [out, in] row-major, bias)` pairs, input layer first) and
/// metadata as a policy directory. Used by the trainer's export and by tests.
pub fn write_policy(
    dir: &Path,
    meta: &PolicyMetadata,
    layers: &[(Vec<f32>, Vec<f32>)],
) -> Result<(), PolicyError> {
    let mut widths = vec![meta.scaling.input_len()];
    widths.extend(&meta.hidden);
    widths.push(ACTION_DIM);
    if layers.len() + 1 != widths.len() {
        return Err(PolicyError::Weights(format!(
            "{} layers for widths {widths:?}",
            layers.len()
        )));
    }
    let mut bytes: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    for (i, ((w, b), io)) in layers.iter().zip(widths.windows(2)).enumerate() {
        if w.len() != io[0] * io[1] || b.len() != io[1] {
            return Err(PolicyError::Weights(format!(
                "layer {i}: {} weights and {} biases for {} -> {}",
                w.len(),
                b.len(),
                io[0],
                io[1]
            )));
        }
        bytes.push((weight_name(i), vec![io[1], io[0]], le_bytes(w)));
        bytes.push((bias_name(i), vec![io[1]], le_bytes(b)));
    }
    let views = bytes
        .iter()
        .map(|(name, shape, data)| {
            safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), data)
                .map(|v| (name.clone(), v))
                .map_err(|e| PolicyError::Weights(format!("{e:?}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let blob =
        safetensors::serialize(views, &None).map_err(|e| PolicyError::Weights(format!("{e:?}")))?;
    let io = |path: std::path::PathBuf| {
        move |source| PolicyError::Io {
            path: path.display().to_string(),
            source,
        }
    };
    std::fs::create_dir_all(dir).map_err(io(dir.to_path_buf()))?;
    let json = serde_json::to_vec_pretty(meta).map_err(|e| PolicyError::Metadata(e.to_string()))?;
    write_atomic(&dir.join(WEIGHTS_FILE), &blob).map_err(io(dir.join(WEIGHTS_FILE)))?;
    write_atomic(&dir.join(METADATA_FILE), &json).map_err(io(dir.join(METADATA_FILE)))?;
    Ok(())
}

/// Replaces the training summary in the metadata of the policy in `dir` (what an exported
/// policy says about itself once it has been evaluated), atomically; the weights stay.
pub fn set_summary(dir: &Path, summary: serde_json::Value) -> Result<(), PolicyError> {
    let path = dir.join(METADATA_FILE);
    let io = |source| PolicyError::Io {
        path: path.display().to_string(),
        source,
    };
    let bytes = std::fs::read(&path).map_err(io)?;
    let mut meta: PolicyMetadata =
        serde_json::from_slice(&bytes).map_err(|e| PolicyError::Metadata(e.to_string()))?;
    if !meta.training.is_object() {
        meta.training = serde_json::json!({});
    }
    meta.training["summary"] = summary;
    let json =
        serde_json::to_vec_pretty(&meta).map_err(|e| PolicyError::Metadata(e.to_string()))?;
    write_atomic(&path, &json).map_err(io)
}

/// Little-endian bytes of `values`.
pub fn le_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Writes `bytes` to a temporary file beside `path`, syncs it and renames it over `path`, so a
/// reader sees the old file or the new one, never half of one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let tmp = path.with_extension("tmp");
    {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, path)?;
    // The rename itself is durable once the directory's entries are.
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => sync_path(dir),
        _ => Ok(()),
    }
}

/// Makes `path` (a file or a directory) durable: its data, or its entries (a rename in it).
pub fn sync_path(path: &Path) -> std::io::Result<()> {
    std::fs::File::open(path)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny(dir: &Path) -> PolicyMetadata {
        let scaling = Scaling {
            beams: 2,
            layout: crate::InputLayout::Paper,
            ..Scaling::default()
        };
        let meta = PolicyMetadata::new(scaling, vec![3], serde_json::json!({}));
        // 4 inputs -> 3 hidden -> 2 outputs.
        let w0: Vec<f32> = (0..12).map(|i| (i as f32 - 6.0) / 10.0).collect();
        let b0 = vec![0.1, -0.2, 0.3];
        let w1 = vec![0.5, -0.5, 1.0, -1.0, 0.25, 0.75];
        let b1 = vec![0.0, 0.1];
        write_policy(dir, &meta, &[(w0, b0), (w1, b1)]).expect("written");
        meta
    }

    #[test]
    fn a_written_policy_loads_and_computes_by_hand() {
        let dir = tempfile::tempdir().expect("tmp");
        let meta = tiny(dir.path());
        let p = Policy::load(dir.path()).expect("loads");
        assert_eq!(p.metadata(), &meta);
        let x = [0.5, 1.0, 0.2, -0.5];
        let w0: Vec<f32> = (0..12).map(|i| (i as f32 - 6.0) / 10.0).collect();
        let b0 = [0.1f32, -0.2, 0.3];
        let h: Vec<f32> = (0..3)
            .map(|r| {
                let s: f32 = (0..4).map(|c| w0[r * 4 + c] * x[c]).sum::<f32>() + b0[r];
                s.max(0.0)
            })
            .collect();
        let o0 = 0.5 * h[0] - 0.5 * h[1] + 1.0 * h[2];
        let o1 = -h[0] + 0.25 * h[1] + 0.75 * h[2] + 0.1;
        let y = p.forward(&x).expect("forward");
        assert!((y[0] - 1.0 / (1.0 + (-o0).exp())).abs() < 1e-6);
        assert!((y[1] - o1.tanh()).abs() < 1e-6);
        assert!(p.forward(&x[..3]).is_err());
    }

    #[test]
    fn broken_files_are_errors_not_panics() {
        let dir = tempfile::tempdir().expect("tmp");
        tiny(dir.path());
        let meta = std::fs::read(dir.path().join(METADATA_FILE)).expect("meta");
        let weights = std::fs::read(dir.path().join(WEIGHTS_FILE)).expect("weights");
        assert!(Policy::from_bytes(b"{", &weights).is_err());
        assert!(Policy::from_bytes(&meta, &weights[..weights.len() / 2]).is_err());
        let mut other: PolicyMetadata = serde_json::from_slice(&meta).expect("json");
        other.hidden = vec![4];
        let other = serde_json::to_vec(&other).expect("json");
        let e = Policy::from_bytes(&other, &weights).expect_err("shape mismatch");
        assert!(e.to_string().contains("shape"), "{e}");
        let missing = tempfile::tempdir().expect("tmp");
        assert!(Policy::load(missing.path()).is_err());
    }

    #[test]
    fn a_residual_policy_with_a_silent_network_is_the_follower() {
        let dir = tempfile::tempdir().expect("tmp");
        let scaling = Scaling::default();
        let mut meta = PolicyMetadata::new(scaling, vec![4], serde_json::json!({}));
        let residual = Residual::follower(&sim::follower::FollowerParams::default());
        meta.residual = Some(residual);
        let n = scaling.input_len();
        let zeros = |k: usize| vec![0.0f32; k];
        write_policy(
            dir.path(),
            &meta,
            &[(zeros(4 * n), zeros(4)), (zeros(8), zeros(2))],
        )
        .expect("written");
        let p = Policy::load(dir.path()).expect("loads");
        assert_eq!(p.metadata().residual, Some(residual));
        for (d, angle) in [(5.0f32, 0.0f32), (0.6, 0.25), (3.0, -2.5), (1.0, 0.3)] {
            let obs = Observation {
                ranges: vec![5.0; scaling.beams],
                goal_distance: d,
                goal_angle: angle,
                velocity: [0.0, 0.0],
            };
            let input = scaling.encode(&obs).expect("encodes");
            let want = residual.output(&scaling, &input);
            let got = p.forward(&input).expect("forward");
            // Equal up to the margin that keeps the base's pre-activation finite.
            assert!(
                (got[0] - want[0]).abs() <= 0.021,
                "{d} {angle}: {got:?} vs {want:?}"
            );
            assert!(
                (got[1] - want[1]).abs() <= 0.021,
                "{d} {angle}: {got:?} vs {want:?}"
            );
        }
        // The metadata of a policy without a base has no `residual` key (older runtimes read it).
        let plain = PolicyMetadata::new(scaling, vec![4], serde_json::json!({}));
        assert!(
            !serde_json::to_string(&plain)
                .expect("json")
                .contains("residual")
        );
    }
}
