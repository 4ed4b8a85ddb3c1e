//! Where a node's kernels run: `device = "cpu" | "gpu"` and `precision = "f64" | "f32"`, read
//! and checked once for every node that has device kernels (fluid, PD), and (feature `gpu`)
//! the one place that opens the GPU context, so keys, errors and log lines read the same.

use protocol::solver::SolverError;

/// Where a node's kernels run and in which arithmetic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Device {
    /// The host's threads, in f64 (the default).
    #[default]
    Cpu,
    /// wgpu compute kernels: f64 where the adapter has `SHADER_F64` (else f32 with a
    /// warning), or f32 when `precision = "f32"` asks for it.
    Gpu { f32: bool },
}

impl Device {
    /// The node's `device` and `precision` values (`None`: key absent). A bad value is a
    /// config error on its key (relative to the node's params, as every node reports keys).
    pub fn parse(device: Option<&str>, precision: Option<&str>) -> Result<Device, SolverError> {
        let gpu = match device {
            None | Some("cpu") => false,
            Some("gpu") => true,
            Some(other) => {
                return Err(SolverError::config(
                    "device",
                    format!("must be \"cpu\" or \"gpu\", got \"{other}\""),
                ));
            }
        };
        let f32 = match precision {
            None | Some("f64") => false,
            Some("f32") if gpu => true,
            Some("f32") => {
                return Err(SolverError::config(
                    "precision",
                    "\"f32\" applies to device = \"gpu\" only (the CPU path is f64)",
                ));
            }
            Some(other) => {
                return Err(SolverError::config(
                    "precision",
                    format!("must be \"f64\" or \"f32\", got \"{other}\""),
                ));
            }
        };
        Ok(if gpu {
            Device::Gpu { f32 }
        } else {
            Device::Cpu
        })
    }

    pub fn is_gpu(self) -> bool {
        matches!(self, Device::Gpu { .. })
    }

    /// The GPU context for `Device::Gpu` (`None` for the CPU), logged as "`what` on the GPU:
    /// adapter, backend, precision" with the f32 warning if any. No adapter is a config error
    /// on `device`: the case asked for something this machine does not have.
    #[cfg(feature = "gpu")]
    pub fn open(
        self,
        what: &str,
    ) -> Result<Option<std::sync::Arc<mechanics::gpu::GpuContext>>, SolverError> {
        use mechanics::gpu::{GpuContext, PrecisionRequest};
        let Device::Gpu { f32 } = self else {
            return Ok(None);
        };
        let req = if f32 {
            PrecisionRequest::ForceF32
        } else {
            PrecisionRequest::Best
        };
        let ctx = GpuContext::with_precision(req)
            .map_err(|e| SolverError::config("device", format!("device = \"gpu\": {e}")))?;
        tracing::info!("{what} on the GPU: {}", ctx.describe());
        if let Some(w) = &ctx.warning {
            tracing::warn!("{w}");
        }
        Ok(Some(std::sync::Arc::new(ctx)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(device: Option<&str>, precision: Option<&str>) -> (String, String) {
        match Device::parse(device, precision) {
            Err(SolverError::Config { key, reason }) => (key, reason),
            other => panic!("{device:?}/{precision:?} accepted or wrong error: {other:?}"),
        }
    }

    #[test]
    fn every_accepted_pair_and_its_device() {
        let cases = [
            (None, None, Device::Cpu),
            (Some("cpu"), None, Device::Cpu),
            (Some("cpu"), Some("f64"), Device::Cpu),
            (Some("gpu"), None, Device::Gpu { f32: false }),
            (Some("gpu"), Some("f64"), Device::Gpu { f32: false }),
            (Some("gpu"), Some("f32"), Device::Gpu { f32: true }),
        ];
        for (d, p, want) in cases {
            assert_eq!(Device::parse(d, p).ok(), Some(want), "{d:?}/{p:?}");
        }
    }

    #[test]
    fn bad_values_name_their_key() {
        let (key, reason) = refusal(Some("tpu"), None);
        assert_eq!(key, "device");
        assert_eq!(reason, "must be \"cpu\" or \"gpu\", got \"tpu\"");
        let (key, reason) = refusal(None, Some("f32"));
        assert_eq!(key, "precision");
        assert_eq!(
            reason,
            "\"f32\" applies to device = \"gpu\" only (the CPU path is f64)"
        );
        let (key, reason) = refusal(Some("gpu"), Some("f16"));
        assert_eq!(key, "precision");
        assert_eq!(reason, "must be \"f64\" or \"f32\", got \"f16\"");
    }
}
