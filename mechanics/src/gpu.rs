//! Shared GPU plumbing for the solver nodes' compute paths (seed 002 §4 runs its FVM
//! and SPH kernels on one GPU): device acquisition through wgpu, the arithmetic precision
//! (f64 where the adapter has `SHADER_F64`, otherwise f32 with a warning), error scopes that
//! turn wgpu validation / out-of-memory / internal errors into `Err` instead of a panic, and
//! helpers for storage buffers, uploads and readbacks.
//!
//! The instance is configured from the environment (`WGPU_BACKEND=vulkan` pins Vulkan;
//! Mesa's lavapipe has `SHADER_F64`). Without any adapter, [`GpuContext::new`] returns
//! [`GpuUnavailable`], whose text is the skip message GPU tests print — outside CI only:
//! under `CI=true` a test that finds no adapter fails ([`skip_or_fail`]), so a CI machine
//! that lost its driver cannot pass the GPU tests by skipping them.

use std::fmt;
use std::sync::{Arc, Mutex};
/// Re-exported so solver crates use the same wgpu without their own dependency line.
pub use wgpu;
use wgpu::util::DeviceExt;

/// Arithmetic precision of the device kernels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Precision {
    F64,
    F32,
}

impl Precision {
    /// WGSL scalar type name.
    pub fn wgsl(self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
        }
    }
    /// Bytes per real.
    pub fn bytes(self) -> usize {
        match self {
            Precision::F64 => 8,
            Precision::F32 => 4,
        }
    }
}

/// No usable adapter (or device) on this machine; the text says why and how to get one.
#[derive(Debug, Clone, PartialEq)]
pub struct GpuUnavailable {
    pub reason: String,
}

impl fmt::Display for GpuUnavailable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "no GPU adapter: {} (install mesa-vulkan-drivers and set WGPU_BACKEND=vulkan to run on lavapipe)",
            self.reason
        )
    }
}

impl std::error::Error for GpuUnavailable {}

/// A failure of GPU work after the device exists (validation, out of memory, device lost,
/// mapping), with wgpu's message.
#[derive(Debug, Clone, PartialEq)]
pub struct GpuError(pub String);

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "GPU error: {}", self.0)
    }
}

impl std::error::Error for GpuError {}

/// Which precision to ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PrecisionRequest {
    /// f64 when the adapter has `SHADER_F64`, else f32 with a warning.
    #[default]
    Best,
    /// f32 even when f64 exists (tests of the fallback path).
    ForceF32,
}

/// How a compute shader binds one buffer (`GpuContext::bind_layout`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BufferBinding {
    Uniform,
    /// A uniform buffer bound at a dynamic offset (one slice per dispatch).
    UniformDynamic,
    /// Storage, read only.
    Read,
    /// Storage, read and write.
    ReadWrite,
}

/// Device, queue and what was negotiated.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub precision: Precision,
    /// Set when the kernels run in f32: a sentence for the log and `summary.json`.
    pub warning: Option<String>,
    pub limits: wgpu::Limits,
    /// Timestamp queries are enabled (the adapter has `TIMESTAMP_QUERY`): kernel profiles
    /// ([`GpuContext::timer`]) can time each dispatch on the device's own clock.
    pub timestamps: bool,
    /// Errors no scope caught (recorded instead of wgpu's default panic).
    uncaptured: Arc<Mutex<Vec<String>>>,
}

impl fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.describe())
            .field("precision", &self.precision)
            .finish()
    }
}

impl GpuContext {
    /// The best adapter the environment allows, f64 when it can.
    pub fn new() -> Result<GpuContext, GpuUnavailable> {
        Self::with_precision(PrecisionRequest::Best)
    }

    /// Acquire a device; prefers an adapter with `SHADER_F64`, then a discrete/integrated GPU.
    pub fn with_precision(req: PrecisionRequest) -> Result<GpuContext, GpuUnavailable> {
        pollster::block_on(Self::acquire(req))
    }

    async fn acquire(req: PrecisionRequest) -> Result<GpuContext, GpuUnavailable> {
        let desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        let backends = desc.backends;
        let instance = wgpu::Instance::new(desc);
        let rank = |a: &wgpu::Adapter| {
            let f64_ok = a.features().contains(wgpu::Features::SHADER_F64);
            let ty = match a.get_info().device_type {
                wgpu::DeviceType::DiscreteGpu => 3,
                wgpu::DeviceType::IntegratedGpu => 2,
                wgpu::DeviceType::VirtualGpu => 1,
                _ => 0,
            };
            (f64_ok as u32) * 10 + ty
        };
        let mut adapters = instance.enumerate_adapters(backends).await;
        adapters.sort_by_key(|a| std::cmp::Reverse(rank(a)));
        let adapter = match adapters.into_iter().next() {
            Some(a) => a,
            None => instance
                .request_adapter(&wgpu::RequestAdapterOptions::default())
                .await
                .map_err(|e| GpuUnavailable {
                    reason: e.to_string(),
                })?,
        };
        let info = adapter.get_info();
        let has_f64 = adapter.features().contains(wgpu::Features::SHADER_F64);
        let (precision, warning) = match (has_f64, req) {
            (true, PrecisionRequest::Best) => (Precision::F64, None),
            (true, PrecisionRequest::ForceF32) => (
                Precision::F32,
                Some(format!(
                    "GPU kernels run in f32 on request (adapter '{}' has SHADER_F64)",
                    info.name
                )),
            ),
            (false, _) => (
                Precision::F32,
                Some(format!(
                    "adapter '{}' ({:?}) has no SHADER_F64: GPU kernels run in f32 (about 1e-6 relative accuracy instead of 1e-15)",
                    info.name, info.backend
                )),
            ),
        };
        let alimits = adapter.limits();
        // ask for what the adapter has for the limits the kernels care about
        let limits = wgpu::Limits {
            max_storage_buffers_per_shader_stage: alimits.max_storage_buffers_per_shader_stage,
            max_storage_buffer_binding_size: alimits.max_storage_buffer_binding_size,
            max_buffer_size: alimits.max_buffer_size,
            max_compute_workgroups_per_dimension: alimits.max_compute_workgroups_per_dimension,
            ..wgpu::Limits::downlevel_defaults()
        };
        let mut required_features = if precision == Precision::F64 {
            wgpu::Features::SHADER_F64
        } else {
            wgpu::Features::empty()
        };
        // timestamps cost nothing unless a profile writes them
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        if timestamps {
            required_features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("cosim compute"),
                required_features,
                required_limits: limits.clone(),
                ..Default::default()
            })
            .await
            .map_err(|e| GpuUnavailable {
                reason: format!("adapter '{}' refused a device: {e}", info.name),
            })?;
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let sink = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut v) = sink.lock() {
                v.push(e.to_string());
            }
        }));
        Ok(GpuContext {
            device,
            queue,
            info,
            precision,
            warning,
            limits,
            timestamps,
            uncaptured,
        })
    }

    /// "llvmpipe (LLVM 15.0.6, 256 bits) on Vulkan (Cpu), f64".
    pub fn describe(&self) -> String {
        format!(
            "{} on {:?} ({:?}), {}",
            self.info.name,
            self.info.backend,
            self.info.device_type,
            self.precision.wgsl()
        )
    }

    /// Run `f` inside validation, out-of-memory and internal error scopes; any error caught
    /// (or recorded by the uncaptured handler meanwhile) becomes `Err`.
    pub fn checked<R>(&self, what: &str, f: impl FnOnce() -> R) -> Result<R, GpuError> {
        let s1 = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let s2 = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let s3 = self.device.push_error_scope(wgpu::ErrorFilter::Internal);
        let r = f();
        let e3 = pollster::block_on(s3.pop());
        let e2 = pollster::block_on(s2.pop());
        let e1 = pollster::block_on(s1.pop());
        if let Some(e) = e1.or(e2).or(e3) {
            return Err(GpuError(format!("{what}: {e}")));
        }
        self.take_uncaptured(what)?;
        Ok(r)
    }

    /// Err with the first error no scope caught since the last call.
    pub fn take_uncaptured(&self, what: &str) -> Result<(), GpuError> {
        let mut v = self
            .uncaptured
            .lock()
            .map_err(|_| GpuError("error log poisoned".into()))?;
        if v.is_empty() {
            return Ok(());
        }
        let msg = v.join("; ");
        v.clear();
        Err(GpuError(format!("{what}: {msg}")))
    }

    /// Compile a WGSL module (errors become `Err`).
    pub fn shader(&self, label: &str, src: &str) -> Result<wgpu::ShaderModule, GpuError> {
        self.checked(&format!("compiling shader '{label}'"), || {
            self.device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(label),
                    source: wgpu::ShaderSource::Wgsl(src.into()),
                })
        })
    }

    /// A compute bind-group layout: binding `i` is a buffer of kind `bindings[i]`.
    pub fn bind_layout(&self, label: &str, bindings: &[BufferBinding]) -> wgpu::BindGroupLayout {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupLayoutEntry {
                binding: i as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: match b {
                        BufferBinding::Uniform | BufferBinding::UniformDynamic => {
                            wgpu::BufferBindingType::Uniform
                        }
                        BufferBinding::Read => wgpu::BufferBindingType::Storage { read_only: true },
                        BufferBinding::ReadWrite => {
                            wgpu::BufferBindingType::Storage { read_only: false }
                        }
                    },
                    has_dynamic_offset: *b == BufferBinding::UniformDynamic,
                    min_binding_size: None,
                },
                count: None,
            })
            .collect();
        self.device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries: &entries,
            })
    }

    /// One compute pipeline per entry point of `module`, all on one layout of `groups`.
    pub fn pipelines(
        &self,
        label: &str,
        groups: &[Option<&wgpu::BindGroupLayout>],
        module: &wgpu::ShaderModule,
        entry_points: &[&str],
    ) -> Vec<wgpu::ComputePipeline> {
        let layout = self
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: groups,
                immediate_size: 0,
            });
        entry_points
            .iter()
            .map(|e| {
                self.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(e),
                        layout: Some(&layout),
                        module,
                        entry_point: Some(e),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            })
            .collect()
    }

    /// A bind group of whole buffers, binding `i` = `buffers[i]`.
    pub fn bind_group(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    }

    /// Zeroed storage buffer of `bytes` (rounded up to 4), copyable both ways.
    pub fn storage(&self, label: &str, bytes: usize) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (bytes.max(4).div_ceil(4) * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Storage buffer initialised with `bytes`.
    pub fn storage_init(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        let mut data = bytes.to_vec();
        data.resize(bytes.len().max(4).div_ceil(4) * 4, 0);
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &data,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// Uniform buffer initialised with `bytes`.
    pub fn uniform_init(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// Write `bytes` at `offset` of `buf` (ordered before the next submission).
    pub fn upload(&self, buf: &wgpu::Buffer, offset: u64, bytes: &[u8]) {
        self.queue.write_buffer(buf, offset, bytes);
    }

    /// Copy `len` bytes at `offset` of `buf` to the host (blocks until the device is done).
    pub fn read(&self, buf: &wgpu::Buffer, offset: u64, len: u64) -> Result<Vec<u8>, GpuError> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: len.max(4).div_ceil(4) * 4,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("read"),
            });
        enc.copy_buffer_to_buffer(buf, offset, &staging, 0, len.div_ceil(4) * 4);
        self.submit_and_map(enc, &staging)?;
        let out = {
            let view = staging
                .get_mapped_range(..)
                .map_err(|e| GpuError(format!("mapping readback: {e}")))?;
            view[..len as usize].to_vec()
        };
        staging.unmap();
        Ok(out)
    }

    /// Submit `enc` (which ends with a copy into the MAP_READ buffer `staging`), wait, and map
    /// `staging` for reading; the caller reads `staging.get_mapped_range(..)` then unmaps.
    pub fn submit_and_map(
        &self,
        enc: wgpu::CommandEncoder,
        staging: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let (tx, rx) = std::sync::mpsc::channel();
        self.checked("submitting GPU work", || {
            self.queue.submit(Some(enc.finish()));
            staging.map_async(wgpu::MapMode::Read, .., move |r| {
                let _ = tx.send(r);
            });
        })?;
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError(format!("waiting for the device: {e}")))?;
        match rx.recv() {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => Err(GpuError(format!("mapping readback: {e}"))),
            Err(_) => Err(GpuError("readback callback never ran".into())),
        }?;
        self.take_uncaptured("GPU work")
    }
}

/// Device-clock timing of compute passes (needs [`GpuContext::timestamps`]): slot `i` is a
/// pass that begins with [`GpuTimer::writes`]`(i)`; after the submission, [`GpuTimer::read`]
/// gives each slot's seconds between the start and the end of its pass.
pub struct GpuTimer {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    staging: wgpu::Buffer,
    slots: u32,
    period_ns: f64,
}

/// Most passes one [`GpuTimer`] times (two queries each; wgpu allows 4096 per set).
pub const TIMER_SLOTS: u32 = 2048;

impl GpuTimer {
    /// Timestamp writes at the start and the end of the pass of `slot`.
    pub fn writes(&self, slot: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        assert!(slot < self.slots, "timer slot {slot} of {}", self.slots);
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * slot),
            end_of_pass_write_index: Some(2 * slot + 1),
        }
    }

    /// Resolve the first `used` slots into the readback buffer (encode after the passes).
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder, used: u32) {
        let q = 2 * used.min(self.slots);
        if q == 0 {
            return;
        }
        enc.resolve_query_set(&self.set, 0..q, &self.resolved, 0);
        enc.copy_buffer_to_buffer(&self.resolved, 0, &self.staging, 0, 8 * q as u64);
    }

    /// Seconds of each of the first `used` slots (after the submission that resolved them).
    pub fn read(&self, ctx: &GpuContext, used: u32) -> Result<Vec<f64>, GpuError> {
        let q = 2 * used.min(self.slots) as usize;
        if q == 0 {
            return Ok(Vec::new());
        }
        let (tx, rx) = std::sync::mpsc::channel();
        self.staging
            .map_async(wgpu::MapMode::Read, ..8 * q as u64, move |r| {
                let _ = tx.send(r);
            });
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError(format!("waiting for the device: {e}")))?;
        match rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(GpuError(format!("mapping timestamps: {e}"))),
            Err(_) => return Err(GpuError("timestamp callback never ran".into())),
        }
        let out = {
            let view = self
                .staging
                .get_mapped_range(..8 * q as u64)
                .map_err(|e| GpuError(format!("mapping timestamps: {e}")))?;
            view.chunks_exact(16)
                .map(|c| {
                    let t0 = u64::from_le_bytes(c[..8].try_into().unwrap_or([0; 8]));
                    let t1 = u64::from_le_bytes(c[8..].try_into().unwrap_or([0; 8]));
                    t1.saturating_sub(t0) as f64 * self.period_ns * 1e-9
                })
                .collect()
        };
        self.staging.unmap();
        Ok(out)
    }
}

/// The device's own streaming bandwidth, bytes moved (read + written) per second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bandwidth {
    /// `copy_buffer_to_buffer` (the copy engine or the driver's copy kernel).
    pub copy: f64,
    /// A WGSL kernel copying 16 bytes per invocation: the bound a compute kernel can reach.
    pub kernel: f64,
    /// Bytes of the buffer copied.
    pub bytes: u64,
    /// Copies timed (per way, after one untimed warm-up of each).
    pub repeats: u32,
}

impl GpuContext {
    /// A timer of `slots` passes, or `None` without timestamp queries.
    pub fn timer(&self, slots: u32) -> Option<GpuTimer> {
        if !self.timestamps || slots == 0 {
            return None;
        }
        let slots = slots.min(TIMER_SLOTS);
        let set = self.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("kernel timer"),
            ty: wgpu::QueryType::Timestamp,
            count: 2 * slots,
        });
        let bytes = 16 * slots as u64;
        let resolved = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamps"),
            size: bytes,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamp readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Some(GpuTimer {
            set,
            resolved,
            staging,
            slots,
            period_ns: self.queue.get_timestamp_period() as f64,
        })
    }

    /// Measure [`Bandwidth`] on two buffers of `bytes` (rounded down to 16, capped by the
    /// adapter's largest buffer and storage binding), `repeats` copies each way, timed on
    /// the host around one submission each (so the figure includes one submission's
    /// overhead, negligible at the sizes that measure bandwidth). The source holds a pattern
    /// (word i of 16-byte element k: k · 4 + i + 1, never zero); after each way the first,
    /// middle and last elements of the destination are read back and must equal it, so a
    /// copy that skipped part of the buffer is an error, not a fast figure.
    pub fn bandwidth(&self, bytes: u64, repeats: u32) -> Result<Bandwidth, GpuError> {
        let cap = self
            .limits
            .max_buffer_size
            .min(self.limits.max_storage_buffer_binding_size);
        let bytes = bytes.min(cap) / 16 * 16;
        if bytes == 0 || repeats == 0 {
            return Err(GpuError("bandwidth: nothing to copy".into()));
        }
        let src = self.storage("bandwidth src", bytes as usize);
        let dst = self.storage("bandwidth dst", bytes as usize);
        let module = self.shader(
            "copy",
            "@group(0) @binding(0) var<storage, read_write> src: array<vec4<u32>>;\n\
             @group(0) @binding(1) var<storage, read_write> dst: array<vec4<u32>>;\n\
             fn at(g: vec3<u32>, n: vec3<u32>) -> u32 { return g.x + g.y * n.x * 256u; }\n\
             @compute @workgroup_size(256)\n\
             fn fill(@builtin(global_invocation_id) g: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>) {\n\
                 let i = at(g, n);\n\
                 if i < arrayLength(&src) { src[i] = vec4<u32>(4u * i + 1u, 4u * i + 2u, 4u * i + 3u, 4u * i + 4u); }\n\
             }\n\
             @compute @workgroup_size(256)\n\
             fn copy(@builtin(global_invocation_id) g: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>) {\n\
                 let i = at(g, n);\n\
                 if i < arrayLength(&src) { dst[i] = src[i]; }\n\
             }\n",
        )?;
        use BufferBinding::ReadWrite;
        let layout = self.bind_layout("copy", &[ReadWrite, ReadWrite]);
        let pipes = self.checked("copy pipelines", || {
            self.pipelines("copy", &[Some(&layout)], &module, &["fill", "copy"])
        })?;
        let bind = self.bind_group("copy", &layout, &[&src, &dst]);
        let (x, y) = dispatch_dims(
            (bytes / 16).div_ceil(256) as u32,
            self.limits.max_compute_workgroups_per_dimension,
        );
        let dispatch = |enc: &mut wgpu::CommandEncoder, pipe: &wgpu::ComputePipeline| {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipe);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(x, y, 1);
        };
        // (what, the encoded work); the host times the submission and the wait
        let run = |what: &str, enc: wgpu::CommandEncoder| -> Result<f64, GpuError> {
            let t0 = std::time::Instant::now();
            self.checked(what, || self.queue.submit(Some(enc.finish())))?;
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError(format!("waiting for the device: {e}")))?;
            self.take_uncaptured(what)?;
            Ok(t0.elapsed().as_secs_f64())
        };
        let encoder = || {
            self.device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("bandwidth"),
                })
        };
        let mut enc = encoder();
        dispatch(&mut enc, &pipes[0]);
        run("bandwidth: filling the source", enc)?;
        let elements = bytes / 16;
        let check = |way: &str| -> Result<(), GpuError> {
            for k in [0, elements / 2, elements - 1] {
                let got = self.read(&dst, 16 * k, 16)?;
                let want: Vec<u8> = (1..=4u32)
                    .flat_map(|i| (4 * k as u32).wrapping_add(i).to_le_bytes())
                    .collect();
                if got != want {
                    return Err(GpuError(format!(
                        "bandwidth: the {way} left element {k} of {elements} uncopied"
                    )));
                }
            }
            Ok(())
        };
        // each way: one untimed copy, the destination cleared, then the timed copies
        let time = |by_kernel: bool| -> Result<f64, GpuError> {
            let way = if by_kernel {
                "copy kernel"
            } else {
                "buffer copy"
            };
            let mut seconds = 0.0;
            for n in [1, repeats] {
                let mut enc = encoder();
                enc.clear_buffer(&dst, 0, None);
                run(way, enc)?;
                let mut enc = encoder();
                for _ in 0..n {
                    if by_kernel {
                        dispatch(&mut enc, &pipes[1]);
                    } else {
                        enc.copy_buffer_to_buffer(&src, 0, &dst, 0, bytes);
                    }
                }
                seconds = run(way, enc)?;
                check(way)?;
            }
            Ok(seconds)
        };
        let copy = time(false)?;
        let kernel = time(true)?;
        let moved = 2.0 * bytes as f64 * repeats as f64;
        Ok(Bandwidth {
            copy: moved / copy,
            kernel: moved / kernel,
            bytes,
            repeats,
        })
    }
}

/// f64 values → device bytes in `p`.
pub fn reals_to_bytes(p: Precision, x: &[f64]) -> Vec<u8> {
    match p {
        Precision::F64 => bytemuck::cast_slice(x).to_vec(),
        Precision::F32 => {
            let v: Vec<f32> = x.iter().map(|&a| a as f32).collect();
            bytemuck::cast_slice(&v).to_vec()
        }
    }
}

/// Device bytes in `p` → f64 values (written into `out`, whose length sets the count).
pub fn bytes_to_reals(p: Precision, b: &[u8], out: &mut [f64]) -> Result<(), GpuError> {
    let need = out.len() * p.bytes();
    if b.len() < need {
        return Err(GpuError(format!(
            "readback of {} bytes, expected {need}",
            b.len()
        )));
    }
    match p {
        Precision::F64 => {
            for (o, c) in out.iter_mut().zip(b.chunks_exact(8)) {
                let mut w = [0u8; 8];
                w.copy_from_slice(c);
                *o = f64::from_le_bytes(w);
            }
        }
        Precision::F32 => {
            for (o, c) in out.iter_mut().zip(b.chunks_exact(4)) {
                let mut w = [0u8; 4];
                w.copy_from_slice(c);
                *o = f32::from_le_bytes(w) as f64;
            }
        }
    }
    Ok(())
}

/// u32 values as device bytes (little-endian, no copy).
pub fn u32_bytes(x: &[u32]) -> &[u8] {
    bytemuck::cast_slice(x)
}

/// Workgroup counts (x, y) covering `groups` workgroups within the per-dimension limit; the
/// kernels linearise as `gid.x + gid.y * num_workgroups.x * WG`.
pub fn dispatch_dims(groups: u32, max_per_dim: u32) -> (u32, u32) {
    let groups = groups.max(1);
    if groups <= max_per_dim {
        (groups, 1)
    } else {
        let y = groups.div_ceil(max_per_dim);
        (groups.div_ceil(y), y)
    }
}

/// Whether this process runs under CI (`CI=true` or `CI=1`, set by `.ci/run`).
pub fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// The policy of every test that needs something a machine may lack (a GPU adapter, f64
/// kernels, network namespaces): outside CI it prints why `test` is skipped and returns;
/// under CI, where everything it needs is installed, it fails the test with the same text.
pub fn skip_or_fail(test: &str, why: &str) {
    assert!(
        !under_ci(),
        "{test}: cannot run under CI=true: {why} (CI installs what this test needs)"
    );
    println!("{test}: skipped: {why}");
}

/// Largest |a − b| over the largest |b| (the absolute difference where b is all zero), a NaN
/// on either side counting as infinitely far: how the GPU tests measure a device result `a`
/// against the CPU's `b`.
pub fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "compared arrays differ in length");
    let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let diff = a.iter().zip(b).fold(0.0_f64, |m, (x, y)| {
        let e = (x - y).abs();
        if e.is_nan() { f64::INFINITY } else { m.max(e) }
    });
    if scale > 0.0 { diff / scale } else { diff }
}

/// For the tests that compare a GPU path with the CPU to 1e-10: a context with f64 kernels,
/// or `None` after [`skip_or_fail`] (no adapter, or f32 kernels only).
pub fn f64_context_or_skip(test: &str) -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(c) if c.precision == Precision::F64 => {
            println!("{test}: GPU {}", c.describe());
            Some(c)
        }
        Ok(c) => {
            skip_or_fail(
                test,
                &format!(
                    "the 1e-10 agreement needs f64 kernels ({})",
                    c.warning.clone().unwrap_or_default()
                ),
            );
            None
        }
        Err(e) => {
            skip_or_fail(test, &e.to_string());
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dispatch_dims_cover_and_respect_limit() {
        for g in [1u32, 7, 65_535, 65_536, 200_001, 1 << 24] {
            let (x, y) = dispatch_dims(g, 65_535);
            assert!(x <= 65_535 && y <= 65_535);
            assert!(x as u64 * y as u64 >= g as u64);
            // not more than one extra row of workgroups
            assert!((x as u64 * y as u64) < g as u64 + x as u64);
        }
    }

    #[test]
    fn real_conversion_round_trips() {
        let x = [1.0, -2.5, 1e-300, 3.0e10];
        let mut y = [0.0; 4];
        bytes_to_reals(Precision::F64, &reals_to_bytes(Precision::F64, &x), &mut y).unwrap();
        assert_eq!(x, y);
        bytes_to_reals(
            Precision::F32,
            &reals_to_bytes(Precision::F32, &x[..2]),
            &mut y[..2],
        )
        .unwrap();
        assert_eq!(&x[..2], &y[..2]);
        assert!(bytes_to_reals(Precision::F64, &[0u8; 8], &mut y).is_err());
    }

    /// A device (or a clear reason why not); on a device, y = 2x + y in the negotiated
    /// precision is exact, and a shader error becomes `Err`, not a panic.
    /// The timer times every pass it was given (a kernel doing real work takes longer than
    /// nothing); the bandwidth copies the whole buffer each way (it checks the destination
    /// itself and errs otherwise) and reports positive rates.
    #[test]
    fn timer_and_bandwidth() {
        let ctx = match GpuContext::new() {
            Ok(c) => c,
            Err(e) => {
                skip_or_fail("timer_and_bandwidth", &e.to_string());
                return;
            }
        };
        let bw = ctx.bandwidth(4 << 20, 3).expect("bandwidth");
        println!(
            "{}: copy {:e} B/s, kernel {:e} B/s",
            ctx.describe(),
            bw.copy,
            bw.kernel
        );
        assert_eq!((bw.bytes, bw.repeats), (4 << 20, 3));
        assert!(bw.copy > 0.0 && bw.kernel > 0.0);
        // a size that is not a whole number of workgroups (the last element still copied)
        let odd = ctx
            .bandwidth(16 * 1000 + 7, 1)
            .expect("bandwidth, odd size");
        assert_eq!(odd.bytes, 16 * 1000);

        let Some(timer) = ctx.timer(3) else {
            skip_or_fail(
                "timer_and_bandwidth",
                "the adapter has no timestamp queries",
            );
            return;
        };
        let m = ctx
            .shader(
                "spin",
                "@group(0) @binding(0) var<storage, read_write> y: array<u32>;
                 @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) g: vec3<u32>) {
                     var a = g.x;
                     for (var k = 0u; k < 4096u; k++) { a = a * 1664525u + 1013904223u; }
                     if g.x < arrayLength(&y) { y[g.x] = a; }
                 }",
            )
            .unwrap();
        let layout = ctx.bind_layout("spin", &[BufferBinding::ReadWrite]);
        let pipe = ctx.pipelines("spin", &[Some(&layout)], &m, &["main"]);
        let y = ctx.storage("y", 4 * 65536);
        let bind = ctx.bind_group("spin", &layout, &[&y]);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for slot in 0..3 {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: Some(timer.writes(slot)),
            });
            pass.set_pipeline(&pipe[0]);
            pass.set_bind_group(0, &bind, &[]);
            // slot 0 does no work; slots 1 and 2 spin over 65,536 invocations
            pass.dispatch_workgroups(if slot == 0 { 0 } else { 1024 }, 1, 1);
        }
        timer.resolve(&mut enc, 3);
        ctx.queue.submit(Some(enc.finish()));
        let t = timer.read(&ctx, 3).expect("timestamps");
        println!("pass seconds: {t:?}");
        assert_eq!(t.len(), 3);
        assert!(t[1] > 0.0 && t[2] > 0.0, "{t:?}");
        assert!(t[1] > t[0] && t[2] > t[0], "empty pass not faster: {t:?}");
        let out = ctx.read(&y, 0, 8).unwrap();
        assert_ne!(out, vec![0u8; 8], "the spin kernel wrote nothing");
    }

    #[test]
    fn device_axpy_and_caught_errors() {
        let ctx = match GpuContext::new() {
            Ok(c) => c,
            Err(e) => {
                skip_or_fail("device_axpy_and_caught_errors", &e.to_string());
                return;
            }
        };
        println!("GPU: {}", ctx.describe());
        let t = ctx.precision.wgsl();
        let src = format!(
            "@group(0) @binding(0) var<storage, read> x: array<{t}>;
             @group(0) @binding(1) var<storage, read_write> y: array<{t}>;
             @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) g: vec3<u32>) {{
                 if g.x < arrayLength(&y) {{ y[g.x] = {t}(2.0) * x[g.x] + y[g.x]; }}
             }}"
        );
        let m = ctx.shader("axpy", &src).unwrap();
        let n = 1000usize;
        let xs: Vec<f64> = (0..n).map(|i| i as f64 * 0.25).collect();
        let ys: Vec<f64> = (0..n).map(|i| 1.0 - i as f64).collect();
        let bx = ctx.storage_init("x", &reals_to_bytes(ctx.precision, &xs));
        let by = ctx.storage_init("y", &reals_to_bytes(ctx.precision, &ys));
        let pipe = ctx
            .checked("pipeline", || {
                ctx.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some("axpy"),
                        layout: None,
                        module: &m,
                        entry_point: Some("main"),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            })
            .unwrap();
        let bg = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipe.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: bx.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: by.as_entire_binding(),
                },
            ],
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut p = enc.begin_compute_pass(&Default::default());
            p.set_pipeline(&pipe);
            p.set_bind_group(0, &bg, &[]);
            p.dispatch_workgroups((n as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit(Some(enc.finish()));
        let b = ctx
            .read(&by, 0, (n * ctx.precision.bytes()) as u64)
            .unwrap();
        let mut out = vec![0.0; n];
        bytes_to_reals(ctx.precision, &b, &mut out).unwrap();
        for i in 0..n {
            assert_eq!(out[i], 2.0 * xs[i] + ys[i], "element {i}");
        }
        // an invalid shader is an Err with naga's message
        let bad = ctx.shader("bad", "fn main( { }");
        assert!(bad.is_err(), "a syntax error must be reported");
        println!("caught: {}", bad.unwrap_err());
    }
}
