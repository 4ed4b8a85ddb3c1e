//! GPU path of the `pd-bond` body (issue 8): the bond force loop of `bond.rs` (Silling 2000,
//! pairwise force c·s·ŷ with breaking above s0; seed 000 App. A, seed 001 eq. 183) and the
//! velocity-Verlet step of `integrate.rs`, device-resident. One thread per particle gathers
//! over its own compressed row of bonds (no atomics, no scatter), so the result is the CPU's
//! to round-off; broken bonds are zeroed in the thread's own row, as on the CPU.
//!
//! Data: particle arrays packed into one real buffer (pos | vel | force | fext | vpres | vol,
//! 3 reals per vector), per-particle/per-bond integers into one u32 buffer (prescribed |
//! offsets | nbr), per-bond reals into one (inv_len | coef).

use super::bond::BondModel;
use super::integrate::Body;
use mechanics::gpu::wgpu;
use mechanics::gpu::{
    GpuContext, GpuError, Precision, bytes_to_reals, dispatch_dims, reals_to_bytes,
};
use std::sync::Arc;

const WG: u32 = 64;

const SHADER: &str = r#"
struct P { n: u32, nb: u32, pad0: u32, pad1: u32, dt: real, half_dt: real, rho: real, bf: real }
@group(0) @binding(0) var<uniform> pp: P;
// pos 0, vel 3n, force 6n, fext 9n, vpres 12n, vol 15n
@group(0) @binding(1) var<storage, read_write> pv: array<real>;
// prescribed 0, offsets n, nbr 2n+1
@group(0) @binding(2) var<storage, read> iu: array<u32>;
// inv_len 0, coef nb
@group(0) @binding(3) var<storage, read_write> bd: array<real>;

fn lin(gid: vec3<u32>, nwg: vec3<u32>) -> u32 { return gid.x + gid.y * nwg.x * 64u; }

// integrate.rs kick(): v += dt/2 (f/ρ + f_ext/(ρV)), or the prescribed velocity
fn kick(i: u32) {
    let n = pp.n;
    if iu[i] != 0u {
        for (var d = 0u; d < 3u; d++) {
            pv[3u * n + 3u * i + d] = pv[12u * n + 3u * i + d];
        }
        return;
    }
    let inv_m = real(1.0) / (pp.rho * pv[15u * n + i]);
    for (var d = 0u; d < 3u; d++) {
        let k = 3u * i + d;
        pv[3u * n + k] += pp.half_dt * (pv[6u * n + k] / pp.rho + pv[9u * n + k] * inv_m);
    }
}

@compute @workgroup_size(64)
fn kick_drift(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = lin(gid, nwg);
    if i >= pp.n { return; }
    kick(i);
    for (var d = 0u; d < 3u; d++) {
        pv[3u * i + d] += pp.dt * pv[3u * pp.n + 3u * i + d];
    }
}

@compute @workgroup_size(64)
fn kick_only(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = lin(gid, nwg);
    if i >= pp.n { return; }
    kick(i);
}

// bond.rs row_force(): f_i = Σ_j c_ij (1/|ξ| − 1/|y|) y, breaking bonds with s > s0 first
@compute @workgroup_size(64)
fn force(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = lin(gid, nwg);
    let n = pp.n;
    if i >= n { return; }
    let xx = pv[3u * i];
    let xy = pv[3u * i + 1u];
    let xz = pv[3u * i + 2u];
    var fx = real(0.0);
    var fy = real(0.0);
    var fz = real(0.0);
    let b0 = iu[n + i];
    let b1 = iu[n + i + 1u];
    for (var b = b0; b < b1; b++) {
        let cb = bd[pp.nb + b];
        if cb == real(0.0) { continue; }
        let j = iu[2u * n + 1u + b];
        let yx = pv[3u * j] - xx;
        let yy = pv[3u * j + 1u] - xy;
        let yz = pv[3u * j + 2u] - xz;
        let r = real(1.0) / sqrt(yx * yx + yy * yy + yz * yz);
        let il = bd[b];
        if r < il * pp.bf {
            bd[pp.nb + b] = real(0.0);
            continue;
        }
        let m = cb * (il - r);
        fx += m * yx;
        fy += m * yy;
        fz += m * yz;
    }
    pv[6u * n + 3u * i] = fx;
    pv[6u * n + 3u * i + 1u] = fy;
    pv[6u * n + 3u * i + 2u] = fz;
}
"#;

/// A `pd-bond` body on the device.
pub struct GpuBondBody {
    ctx: Arc<GpuContext>,
    kick_drift: wgpu::ComputePipeline,
    kick_only: wgpu::ComputePipeline,
    force: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    params: wgpu::Buffer,
    pv: wgpu::Buffer,
    bd: wgpu::Buffer,
    n: usize,
    nb: usize,
    rho: f64,
    bf: f64,
    max_wg: u32,
    pub time: f64,
    pub steps: u64,
}

fn flat(v: &[[f64; 3]]) -> &[f64] {
    v.as_flattened()
}

impl GpuBondBody {
    /// Upload `body` (whose model is `model`, built with `critical_stretch`) to the device.
    /// `model` must be the `BondModel` the body holds (its bond coefficients are copied).
    pub fn new(
        ctx: Arc<GpuContext>,
        body: &Body,
        model: &BondModel,
        critical_stretch: Option<f64>,
    ) -> Result<GpuBondBody, GpuError> {
        let n = body.len();
        let nb = body.bonds.len();
        if model.coef.len() != nb {
            return Err(GpuError(format!(
                "the model has {} bond coefficients, the body {nb} bonds",
                model.coef.len()
            )));
        }
        if 2 * n + 1 + nb >= u32::MAX as usize {
            return Err(GpuError(format!("{nb} bonds exceed 32-bit indices")));
        }
        let p = ctx.precision;
        let rb = p.bytes();
        // BondModel::new: break_factor = 1/(1+s0), 0 without damage
        let bf = critical_stretch.map_or(0.0, |s0| 1.0 / (1.0 + s0));
        let module = ctx.shader("pd-bond", &format!("alias real = {};\n{SHADER}", p.wgsl()))?;
        let mut reals = Vec::with_capacity(16 * n);
        for a in [&body.pos, &body.vel, &body.force, &body.fext, &body.vpres] {
            reals.extend_from_slice(flat(a));
        }
        reals.extend_from_slice(&body.vol);
        let mut ints: Vec<u32> = body.prescribed.iter().map(|&x| x as u32).collect();
        ints.extend(body.bonds.offsets.iter().map(|&o| o as u32));
        ints.extend_from_slice(&body.bonds.nbr);
        let mut breal = body.bonds.inv_len.clone();
        breal.extend_from_slice(&model.coef);
        let max_bind = ctx.limits.max_storage_buffer_binding_size as usize;
        if reals.len().max(breal.len()) * rb > max_bind {
            return Err(GpuError(format!(
                "{nb} bonds need more than the adapter's {max_bind} bytes per binding"
            )));
        }
        let (kick_drift, kick_only, force, bind, params, pv, bd) =
            ctx.checked("building the pd-bond pipelines", || {
                let buf = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
                    binding,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                };
                let sto = |read_only| wgpu::BufferBindingType::Storage { read_only };
                let layout =
                    ctx.device
                        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                            label: Some("pd"),
                            entries: &[
                                buf(0, wgpu::BufferBindingType::Uniform),
                                buf(1, sto(false)),
                                buf(2, sto(true)),
                                buf(3, sto(false)),
                            ],
                        });
                let pl = ctx
                    .device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("pd"),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
                let mk = |e: &str| {
                    ctx.device
                        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                            label: Some(e),
                            layout: Some(&pl),
                            module: &module,
                            entry_point: Some(e),
                            compilation_options: Default::default(),
                            cache: None,
                        })
                };
                let (kd, ko, fo) = (mk("kick_drift"), mk("kick_only"), mk("force"));
                let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("pd params"),
                    size: 64,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                let pv = ctx.storage_init("pd particles", &reals_to_bytes(p, &reals));
                let iu = ctx.storage_init("pd ints", mechanics::gpu::u32_bytes(&ints));
                let bd = ctx.storage_init("pd bonds", &reals_to_bytes(p, &breal));
                let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("pd"),
                    layout: &layout,
                    entries: &[
                        entry(&params, 0),
                        entry(&pv, 1),
                        entry(&iu, 2),
                        entry(&bd, 3),
                    ],
                });
                (kd, ko, fo, bind, params, pv, bd)
            })?;
        Ok(GpuBondBody {
            max_wg: ctx.limits.max_compute_workgroups_per_dimension,
            ctx,
            kick_drift,
            kick_only,
            force,
            bind,
            params,
            pv,
            bd,
            n,
            nb,
            rho: body.density,
            bf,
            time: body.time,
            steps: body.steps,
        })
    }

    /// `k` velocity-Verlet steps of size `dt` (integrate.rs `Body::step`), one submission.
    pub fn steps(&mut self, k: u64, dt: f64) -> Result<(), GpuError> {
        let p = self.ctx.precision;
        let mut u = vec![0u8; 64];
        u[0..4].copy_from_slice(&(self.n as u32).to_le_bytes());
        u[4..8].copy_from_slice(&(self.nb as u32).to_le_bytes());
        let r = reals_to_bytes(p, &[dt, 0.5 * dt, self.rho, self.bf]);
        // the first real sits at byte 16 (after 4 u32) for both f32 and f64 alignment
        u[16..16 + r.len()].copy_from_slice(&r);
        self.ctx.upload(&self.params, 0, &u);
        let (x, y) = dispatch_dims((self.n as u32).div_ceil(WG), self.max_wg);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_bind_group(0, &self.bind, &[]);
            for _ in 0..k {
                for pipe in [&self.kick_drift, &self.force, &self.kick_only] {
                    pass.set_pipeline(pipe);
                    pass.dispatch_workgroups(x, y, 1);
                }
            }
        }
        self.ctx.checked("pd-bond steps", || {
            self.ctx.queue.submit(Some(enc.finish()))
        })?;
        for _ in 0..k {
            self.time += dt;
        }
        self.steps += k;
        Ok(())
    }

    /// Copy positions, velocities, forces, time and step count into `body`, and the bond
    /// coefficients (zero = broken) into `coef`.
    pub fn download(&self, body: &mut Body, coef: &mut [f64]) -> Result<(), GpuError> {
        let p = self.ctx.precision;
        let rb = p.bytes();
        let n3 = 3 * self.n;
        let b = self.ctx.read(&self.pv, 0, (3 * n3 * rb) as u64)?;
        let mut all = vec![0.0; 3 * n3];
        bytes_to_reals(p, &b, &mut all)?;
        body.pos.as_flattened_mut().copy_from_slice(&all[..n3]);
        body.vel
            .as_flattened_mut()
            .copy_from_slice(&all[n3..2 * n3]);
        body.force
            .as_flattened_mut()
            .copy_from_slice(&all[2 * n3..]);
        if coef.len() == self.nb {
            let b = self
                .ctx
                .read(&self.bd, (self.nb * rb) as u64, (self.nb * rb) as u64)?;
            bytes_to_reals(p, &b, coef)?;
        }
        body.time = self.time;
        body.steps = self.steps;
        Ok(())
    }

    pub fn precision(&self) -> Precision {
        self.ctx.precision
    }
}

fn entry(b: &wgpu::Buffer, binding: u32) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}
