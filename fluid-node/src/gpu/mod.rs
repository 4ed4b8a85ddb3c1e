//! GPU path of the fluid node (seed 002 §2.3–§2.4 and §4: the whole FVM step on the
//! device). [`GpuEuler`] takes a CPU-built [`Fluid`] (same grid, initial state, boundaries,
//! limiter, CFL number), uploads its conserved state once, and runs the complete time loop on
//! the device — primitive recovery, ghost fill, MUSCL + HLLC fluxes, the three SSP-RK3 stages,
//! the boundary impulse and the CFL reduction — in `euler.wgsl`, which mirrors the CPU kernels
//! operation by operation. Only a few control words cross to the host per batch of steps;
//! the field crosses only when [`GpuEuler::download`] asks for it.
//!
//! Scope: the five-equation model with one to four materials, each an ideal gas, a
//! stiffened gas or JWL detonation products (air, water, explosive products), 1-D, 2-D or
//! 3-D, every boundary kind (wall, symmetry, outflow, periodic, inflow, non-reflecting), with
//! or without an immersed particle interface (its kernels in `immersed.wgsl`, its per-window
//! host work in [`interface`]); probes and edge lines read their cells back per window
//! ([`GpuEuler::cell_states`], [`GpuEuler::volume_fractions`]). What the kernels do not
//! implement (radial grids, a conservative refill) is refused with an error that names the
//! reason.

use crate::boundary::Boundary;
use crate::diagnostics::Totals;
use crate::eos::Material;
use crate::grid::Grid;
use crate::immersed::Immersed;
use crate::limiter::Limiter;
use crate::mixture::Phase;
use crate::model::Fluid;
use crate::step::{RK3, RK3_FLUX_WEIGHT, RK3_PROJECTION_WEIGHT};
use mechanics::gpu::{
    GpuContext, GpuError, GpuUnavailable, Precision, PrecisionRequest, bytes_to_reals,
    dispatch_dims, reals_to_bytes,
};
use protocol::message::StepReport;
use protocol::{Outbox, SolverError, Window};
use std::fmt;
use std::sync::Arc;

mod interface;

const SHADER: &str = include_str!("euler.wgsl");
const IMMERSED_SHADER: &str = include_str!("immersed.wgsl");
/// Storage buffers per shader stage the kernels with an immersed interface bind.
const IMMERSED_STORAGE_BUFFERS: u32 = 9;
/// Workgroup sizes of the shader (WG for cell/face kernels, RWG for reductions).
const WG: u32 = 64;
const RWG: u32 = 256;
/// Control reals before the partial maxima in the `red` buffer.
const NCTRL: usize = 16;
/// Status words.
const NST: usize = 16;
/// Most workgroups per component of the boundary impulse's first level.
const IMPULSE_PARTS: usize = 64;
/// Steps per command buffer within a batch (submitted while the next is encoded).
const CHUNK: u64 = 8;
/// Largest number of steps encoded before the host reads the control words.
const MAX_BATCH: u64 = 256;

/// Why the GPU path cannot run this case.
#[derive(Debug, Clone, PartialEq)]
pub enum GpuSetupError {
    /// No adapter or device on this machine.
    Unavailable(GpuUnavailable),
    /// The model uses something the device kernels do not implement.
    Unsupported(String),
    /// wgpu refused a shader, pipeline or buffer.
    Gpu(GpuError),
}

impl fmt::Display for GpuSetupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GpuSetupError::Unavailable(e) => write!(f, "{e}"),
            GpuSetupError::Unsupported(s) => write!(f, "device = \"gpu\" does not support {s}"),
            GpuSetupError::Gpu(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for GpuSetupError {}

impl From<GpuError> for GpuSetupError {
    fn from(e: GpuError) -> Self {
        GpuSetupError::Gpu(e)
    }
}

impl From<GpuSetupError> for SolverError {
    fn from(e: GpuSetupError) -> Self {
        match e {
            GpuSetupError::Unsupported(_) => SolverError::config("device", e.to_string()),
            _ => SolverError::Other(e.to_string()),
        }
    }
}

fn gpu_err(e: GpuError) -> SolverError {
    SolverError::Other(e.to_string())
}

/// Check that the device kernels implement this model; `Err` names what is missing.
pub fn supports(f: &Fluid) -> Result<(), String> {
    if !f.grid.columns.is_empty() {
        return Err(format!(
            "geometry '{}' (the device kernels run Cartesian grids)",
            f.grid.geometry.name()
        ));
    }
    if !(1..=MAX_MATERIALS).contains(&f.nmat()) {
        return Err(format!(
            "{} materials (the device kernels take 1 to {MAX_MATERIALS})",
            f.nmat()
        ));
    }
    if f.nv != 2 * f.nmat() + 3 {
        return Err(format!(
            "{} variables per cell (expected {})",
            f.nv,
            2 * f.nmat() + 3
        ));
    }
    if f.immersed.as_ref().is_some_and(|im| im.conservative) {
        return Err("immersed.refill = \"conservative\" (the device's wall fluxes do not keep what they carry into the solid's cells)".into());
    }
    Ok(())
}

/// Most materials the device kernels take (the CPU's limit too).
const MAX_MATERIALS: usize = 4;
/// First real parameter of the materials' constants, and reals per material (`euler.wgsl`
/// `MAT0`, `MAT`); the inflow states follow the last material's slot.
const MAT0: usize = 50;
const MAT: usize = 12;

/// The constants of material `ph` as `euler.wgsl` reads them: 1/Γ, the offset −p_ref/Γ of a
/// constant-reference phase, Γ, γ and p∞ of an ideal or stiffened gas (ρc² = γ (p + p∞);
/// p∞ = 0 for an ideal gas), and JWL's ρ0, A, B, R1, R2, ω; and whether it is JWL.
fn material_constants(ph: &Phase) -> ([f64; MAT], bool) {
    use crate::eos::Eos;
    let mut c = [0.0; MAT];
    c[0] = ph.inv_g;
    c[1] = ph.off;
    c[2] = ph.eos.gruneisen();
    match &ph.eos {
        Material::Ideal(g) => {
            c[3] = g.gamma;
            (c, false)
        }
        Material::Stiffened(s) => {
            c[3] = s.gamma;
            c[4] = s.p_inf;
            (c, false)
        }
        Material::Jwl(j) => {
            c[5..11].copy_from_slice(&[j.rho0, j.a, j.b, j.r1, j.r2, j.omega]);
            (c, true)
        }
    }
}

/// The exponential of the JWL reference curve in the shader's precision. WGSL's `exp` is
/// f32 only (Vulkan has no f64 exponential), so the f64 kernels compute e^x = 2^k e^r with
/// r = x − k ln 2 (ln 2 in two parts, exact products for |k| < 2048), e^r by its Taylor
/// series to r^15 in Horner form (|r| ≤ ½ ln 2: a truncation near 1e-19 relative) and 2^k
/// exactly by `ldexp`: within a few units in the last place of the CPU's `exp`.
fn exp_source(p: Precision) -> &'static str {
    match p {
        Precision::F32 => "fn rexp(x: real) -> real { return exp(x); }\n",
        Precision::F64 => {
            "fn rexp(x: real) -> real {
    if x < real(-746.0) {
        return real(0.0);
    }
    let k = floor(x * real(1.4426950408889634) + real(0.5));
    let r = (x - k * real(6.93147180369123816490e-01)) - k * real(1.90821492927058770002e-10);
    var e = real(7.647163731819816e-13);
    e = e * r + real(1.1470745597729725e-11);
    e = e * r + real(1.6059043836821613e-10);
    e = e * r + real(2.08767569878681e-09);
    e = e * r + real(2.505210838544172e-08);
    e = e * r + real(2.755731922398589e-07);
    e = e * r + real(2.7557319223985893e-06);
    e = e * r + real(2.48015873015873e-05);
    e = e * r + real(0.0001984126984126984);
    e = e * r + real(0.001388888888888889);
    e = e * r + real(0.008333333333333333);
    e = e * r + real(0.041666666666666664);
    e = e * r + real(0.16666666666666666);
    e = e * r + real(0.5);
    e = e * r + real(1.0);
    e = e * r + real(1.0);
    return ldexp(e, i32(k));
}
"
        }
    }
}

/// The immersed interface's window outputs on the GPU path, as the CPU path of
/// `EulerSolver::advance` writes them: the window-averaged force on each particle into `out`,
/// the interface impulse, the reclassification momentum (counted with the external impulse)
/// and its scalars into `report`. Returns the window's work of the particle impulses at the
/// particle velocities (to subtract from the interface work).
pub fn immersed_outputs(
    im: &Immersed,
    nd: usize,
    w: &Window,
    out: &mut Outbox,
    report: &mut StepReport,
) -> f64 {
    let buf = out.put(&im.interface, "force", 3, im.n);
    im.forces(w.t1 - w.t0, buf);
    let work = im
        .impulse
        .iter()
        .zip(&im.velocities)
        .map(|(j, v)| j[0] * v[0] + j[1] * v[1] + j[2] * v[2])
        .sum::<f64>();
    for c in 0..3 {
        report.interface_impulse[c] = -im.total_impulse[c];
        report.external_impulse[c] += im.reclass_momentum[c];
    }
    report.external_work += im.reclass_energy;
    report
        .scalars
        .push(("reclassification_energy".into(), im.reclass_energy));
    for (c, axis) in ["x", "y", "z"].iter().enumerate().take(nd) {
        report.scalars.push((
            format!("reclassification_momentum_{axis}"),
            im.reclass_momentum[c],
        ));
    }
    work
}

fn whole(b: &wgpu::Buffer, binding: u32) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}

fn bc_code(b: &Boundary) -> u32 {
    match b {
        Boundary::Wall | Boundary::Symmetry => 0,
        Boundary::Outflow => 1,
        Boundary::Periodic => 2,
        Boundary::Inflow(_) => 3,
        Boundary::NonReflecting(_) => 4,
    }
}

/// The kernels of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kernel {
    PrimRate,
    PrimOnly,
    ReduceDt,
    Ghost(usize),
    Flux(usize),
    Impulse,
    ImpulseSum,
    Update,
    Finish,
    ImFill,
    ImWall,
    ImProject,
    ImTotal,
}

impl Kernel {
    fn name(self) -> &'static str {
        match self {
            Kernel::PrimRate => "prim_rate",
            Kernel::PrimOnly => "prim_only",
            Kernel::ReduceDt => "reduce_dt",
            Kernel::Ghost(0) => "ghost_x",
            Kernel::Ghost(1) => "ghost_y",
            Kernel::Ghost(_) => "ghost_z",
            Kernel::Flux(0) => "flux_x",
            Kernel::Flux(1) => "flux_y",
            Kernel::Flux(_) => "flux_z",
            Kernel::Impulse => "impulse",
            Kernel::ImpulseSum => "impulse_sum",
            Kernel::Update => "update",
            Kernel::Finish => "finish",
            Kernel::ImFill => "im_fill",
            Kernel::ImWall => "im_wall",
            Kernel::ImProject => "im_project",
            Kernel::ImTotal => "im_total",
        }
    }
}

/// One dispatch of a step: which kernel, at which RK stage's uniforms, how many workgroups.
#[derive(Debug, Clone, Copy)]
struct Planned {
    kernel: Kernel,
    stage: usize,
    dims: (u32, u32),
}

/// One kernel's share of a step, measured by [`GpuEuler::profile`].
#[derive(Debug, Clone, PartialEq)]
pub struct KernelProfile {
    /// The entry point in the shader.
    pub kernel: &'static str,
    /// Dispatches per step.
    pub dispatches: u32,
    /// Device seconds per step (all its dispatches).
    pub seconds: f64,
    /// Bytes per step it must move at the least (see `compulsory_bytes`).
    pub bytes: u64,
}

struct Pipes {
    prim_rate: wgpu::ComputePipeline,
    prim_only: wgpu::ComputePipeline,
    reduce_dt: wgpu::ComputePipeline,
    ghost: [wgpu::ComputePipeline; 3],
    flux: [wgpu::ComputePipeline; 3],
    update: wgpu::ComputePipeline,
    impulse: wgpu::ComputePipeline,
    impulse_sum: wgpu::ComputePipeline,
    finish: wgpu::ComputePipeline,
    row_totals: wgpu::ComputePipeline,
}

/// The device-resident Euler solver of one fluid model.
pub struct GpuEuler {
    ctx: Arc<GpuContext>,
    pipes: Pipes,
    bind: wgpu::BindGroup,
    /// Byte offset of each RK stage's uniform block.
    stage_off: [u32; 3],
    cons: wgpu::Buffer,
    flux: wgpu::Buffer,
    red: wgpu::Buffer,
    st: wgpu::Buffer,
    staging: wgpu::Buffer,
    /// Values per state array (rows · nv · mx, the CPU layout).
    len: usize,
    /// Conserved values per cell (2·NM + 3).
    nv: usize,
    /// Row length (cells per x-line with ghosts).
    mx: usize,
    grid: Grid,
    /// The materials (for probes and error messages).
    phases: Vec<Phase>,
    nd: usize,
    /// Thread counts of each kernel.
    cells: u32,
    ghost_n: [u32; 3],
    face_n: [u32; 3],
    max_wg: u32,
    /// Workgroups per component of the boundary impulse's first level.
    iparts: u32,
    // host mirror of the device clock
    time: f64,
    steps: u64,
    impulse: [f64; 3],
    /// `Fluid::boundary_work` (control slot 7).
    work: f64,
    last_dt: f64,
    /// Steps allowed per `advance_to` before giving up (the CPU's max_steps_per_window).
    max_steps: u64,
    /// The immersed interface's kernels and tables (models with `[immersed]`).
    im: Option<interface::ImDevice>,
}

impl GpuEuler {
    /// Build on the best adapter of this machine (f64 where possible).
    pub fn new(f: &Fluid) -> Result<GpuEuler, GpuSetupError> {
        Self::with_precision(f, PrecisionRequest::Best)
    }

    /// As `new`, with the arithmetic asked for (f32 on request, with a warning).
    pub fn with_precision(f: &Fluid, req: PrecisionRequest) -> Result<GpuEuler, GpuSetupError> {
        supports(f).map_err(GpuSetupError::Unsupported)?;
        let ctx = GpuContext::with_precision(req).map_err(GpuSetupError::Unavailable)?;
        Self::with_context(Arc::new(ctx), f)
    }

    /// Build on an existing device (shared by several solvers of one process).
    pub fn with_context(ctx: Arc<GpuContext>, f: &Fluid) -> Result<GpuEuler, GpuSetupError> {
        supports(f).map_err(GpuSetupError::Unsupported)?;
        let grid = &f.grid;
        let p = ctx.precision;
        let mx = grid.mx();
        let nm = f.nmat();
        let nv = f.nv;
        // flux entries per face: the face velocity too with several materials
        let nf = if nm == 1 { nv } else { nv + 1 };
        let len = grid.rows() * nv * mx;
        let rb = p.bytes();
        let max_bind = ctx.limits.max_storage_buffer_binding_size;
        // one flux array per direction (row_totals also uses it as scratch: 10 reals a row)
        let flux_len = (grid.nd * grid.rows() * nf * mx).max(10 * grid.rows());
        if (flux_len * rb) as u64 > max_bind {
            return Err(GpuSetupError::Unsupported(format!(
                "{:?} cells: the flux array needs {} bytes, more than the adapter's {} per binding",
                grid.n,
                flux_len * rb,
                max_bind
            )));
        }
        if len >= u32::MAX as usize / 4 {
            return Err(GpuSetupError::Unsupported(format!(
                "{:?} cells (32-bit indices)",
                grid.n
            )));
        }
        let cells = grid.cells() as u32;
        let nparts = cells.div_ceil(RWG);
        let max_wg = ctx.limits.max_compute_workgroups_per_dimension;
        let fsize = (grid.rows() * nf * mx) as u32;
        // u32 parameters, 8 rows of 4
        let mut pu = [0u32; 32];
        for d in 0..3 {
            pu[d] = grid.n[d] as u32;
            pu[4 + d] = grid.g[d] as u32;
            pu[8 + d] = grid.m[d] as u32;
            for s in 0..2 {
                pu[16 + 4 * d + s] = bc_code(&f.bc[d][s]);
            }
        }
        pu[3] = grid.nd as u32;
        pu[7] = match f.limiter {
            Limiter::Minmod => 0,
            Limiter::VanLeer => 1,
            Limiter::Mc => 2,
        };
        pu[11] = fsize;
        pu[12] = nparts;
        // boundary impulse: workgroups per component, about 8 face pairs a thread, at most 64
        let pairs: usize = (0..grid.nd)
            .map(|d| grid.cells() / grid.n[d])
            .sum::<usize>();
        let iparts = pairs.div_ceil(8 * RWG as usize).clamp(1, IMPULSE_PARTS) as u32;
        pu[13] = iparts;
        // real parameters
        let (inf, maxr, snap, minpos) = match p {
            Precision::F64 => (f64::INFINITY, f64::MAX, 1e-12, f64::MIN_POSITIVE),
            Precision::F32 => (
                f64::INFINITY,
                f32::MAX as f64,
                1e-6,
                f32::MIN_POSITIVE as f64,
            ),
        };
        // 0..3 are free (the materials' constants follow at MAT0)
        let mut prs = vec![
            0.0,
            0.0,
            0.0,
            f.cfl,
            inf,
            maxr,
            snap,
            minpos,
            1.0 / grid.dx[0],
            1.0 / grid.dx[1],
            1.0 / grid.dx[2],
            grid.face_area(0),
            grid.face_area(1),
            grid.face_area(2),
        ];
        // 14..38: each face's far field where it is non-reflecting (`far` in euler.wgsl)
        for d in 0..3 {
            for s in 0..2 {
                match &f.bc[d][s] {
                    Boundary::NonReflecting(far) => prs.extend_from_slice(&[
                        far.impedance,
                        far.relax,
                        far.pressure,
                        far.velocity[d],
                    ]),
                    _ => prs.extend_from_slice(&[0.0; 4]),
                }
            }
        }
        // 38..44 are free
        prs.resize(44, 0.0);
        prs.push(grid.cell_volume());
        // 45..48: projection weights of the RK stages (seed 002 eq. 35)
        prs.extend_from_slice(&RK3_PROJECTION_WEIGHT);
        // the materials' constants from MAT0, a bit per JWL material
        prs.resize(MAT0, 0.0);
        let mut jwl = 0u32;
        for k in 0..MAX_MATERIALS {
            match f.phases.get(k) {
                Some(ph) => {
                    let (c, is_jwl) = material_constants(ph);
                    prs.extend_from_slice(&c);
                    jwl |= u32::from(is_jwl) << k;
                }
                None => prs.extend_from_slice(&[0.0; MAT]),
            }
        }
        // the inflow states (nv primitives per side)
        for d in 0..3 {
            for s in 0..2 {
                match &f.bc[d][s] {
                    Boundary::Inflow(q) if q.len() >= nv => prs.extend_from_slice(&q[..nv]),
                    _ => prs.extend(std::iter::repeat_n(0.0, nv)),
                }
            }
        }
        // stage uniforms at aligned offsets
        let align = ctx.limits.min_uniform_buffer_offset_alignment.max(32) as usize;
        let mut stage_bytes = vec![0u8; 3 * align];
        let mut stage_off = [0u32; 3];
        for s in 0..3 {
            let o = s * align;
            stage_off[s] = o as u32;
            let (a, b) = RK3[s];
            let vals = reals_to_bytes(p, &[a, b, RK3_FLUX_WEIGHT[s]]);
            stage_bytes[o..o + vals.len()].copy_from_slice(&vals);
            let so = o + 3 * rb;
            stage_bytes[so..so + 4].copy_from_slice(&(s as u32).to_le_bytes());
        }
        let stage_size = (3 * rb + 4).div_ceil(rb) * rb;

        let immersed = f.immersed.is_some();
        if immersed && ctx.limits.max_storage_buffers_per_shader_stage < IMMERSED_STORAGE_BUFFERS {
            return Err(GpuSetupError::Unsupported(format!(
                "an immersed interface on this adapter ({} storage buffers per shader stage, the kernels need {IMMERSED_STORAGE_BUFFERS})",
                ctx.limits.max_storage_buffers_per_shader_stage
            )));
        }
        let head = format!(
            "alias real = {};\nconst LIMITER: u32 = {}u;\nconst ND: u32 = {}u;\n\
             const NM: u32 = {nm}u;\nconst NV: u32 = {nv}u;\nconst NF: u32 = {nf}u;\n\
             const JWL: u32 = {jwl}u;\n{}",
            p.wgsl(),
            pu[7],
            grid.nd,
            exp_source(p)
        );
        let src = if immersed {
            format!("{head}{SHADER}\n{IMMERSED_SHADER}")
        } else {
            // without an interface no cell is solid
            format!("{head}{SHADER}\nfn is_solid_cell(c: u32) -> bool {{ return false; }}\n")
        };
        let module = ctx.shader("euler", &src)?;
        let (bgl, layout, pipes, im_parts) = ctx.checked("building the fluid pipelines", || {
            use mechanics::gpu::BufferBinding::{Read, ReadWrite, Uniform, UniformDynamic};
            let bgl = ctx.bind_layout(
                "euler",
                &[
                    Uniform,
                    Read,
                    ReadWrite,
                    ReadWrite,
                    ReadWrite,
                    ReadWrite,
                    ReadWrite,
                    ReadWrite,
                    UniformDynamic,
                ],
            );
            let ibgl = immersed.then(|| interface::layout(&ctx));
            let layout = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("euler"),
                    bind_group_layouts: &[Some(&bgl), ibgl.as_ref()],
                    immediate_size: 0,
                });
            let mk = |entry: &str| {
                ctx.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(&layout),
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            };
            let pipes = Pipes {
                prim_rate: mk("prim_rate"),
                prim_only: mk("prim_only"),
                reduce_dt: mk("reduce_dt"),
                ghost: [mk("ghost_x"), mk("ghost_y"), mk("ghost_z")],
                flux: [mk("flux_x"), mk("flux_y"), mk("flux_z")],
                update: mk("update"),
                impulse: mk("impulse"),
                impulse_sum: mk("impulse_sum"),
                finish: mk("finish"),
                row_totals: mk("row_totals"),
            };
            let im_parts = ibgl.map(|l| {
                (
                    l,
                    [
                        mk("im_fill"),
                        mk("im_wall"),
                        mk("im_project"),
                        mk("im_total"),
                        mk("im_gather"),
                        mk("im_scatter"),
                    ],
                )
            });
            (bgl, layout, pipes, im_parts)
        })?;
        drop(layout);
        let bytes_u32: Vec<u8> = pu.iter().flat_map(|x| x.to_le_bytes()).collect();
        let (bind, cons, flux, red, st, staging) =
            ctx.checked("allocating the fluid buffers", || {
                let b_pu = ctx.uniform_init("params u32", &bytes_u32);
                let b_pr = ctx.storage_init("params real", &reals_to_bytes(p, &prs));
                let cons = ctx.storage_init("cons", &reals_to_bytes(p, &f.cons));
                let cons0 = ctx.storage("cons0", len * rb);
                let prim = ctx.storage("prim", len * rb);
                let flux = ctx.storage("flux", flux_len * rb);
                let red = ctx.storage("red", (NCTRL + nparts as usize + 4 * iparts as usize) * rb);
                let st = ctx.storage("status", NST * 4);
                let stage = ctx.uniform_init("stages", &stage_bytes);
                let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("control readback"),
                    size: (NCTRL * rb + NST * 4) as u64,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("euler"),
                    layout: &bgl,
                    entries: &[
                        whole(&b_pu, 0),
                        whole(&b_pr, 1),
                        whole(&cons, 2),
                        whole(&cons0, 3),
                        whole(&prim, 4),
                        whole(&flux, 5),
                        whole(&red, 6),
                        whole(&st, 7),
                        wgpu::BindGroupEntry {
                            binding: 8,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &stage,
                                offset: 0,
                                size: std::num::NonZeroU64::new(stage_size as u64),
                            }),
                        },
                    ],
                });
                (bind, cons, flux, red, st, staging)
            })?;
        let n = grid.n;
        let g = grid.g;
        let ghost_n = [
            (n[1] * n[2] * 2 * g[0] * nv) as u32,
            (n[2] * 2 * g[1] * nv * mx) as u32,
            (grid.m[1] * 2 * g[2] * nv * mx) as u32,
        ];
        let face_n: [u32; 3] = std::array::from_fn(|d| {
            let mut c = n;
            c[d] += 1;
            (c[0] * c[1] * c[2]) as u32
        });
        let ctx_im = ctx.clone();
        Ok(GpuEuler {
            ctx,
            pipes,
            bind,
            stage_off,
            cons,
            flux,
            red,
            st,
            staging,
            len,
            nv,
            mx,
            grid: grid.clone(),
            phases: f.phases.clone(),
            nd: grid.nd,
            cells,
            ghost_n,
            face_n,
            max_wg,
            iparts,
            time: f.time,
            steps: f.steps,
            impulse: f.boundary_impulse,
            work: f.boundary_work,
            last_dt: 0.0,
            max_steps: f.max_steps_per_window,
            im: match (im_parts, &f.immersed) {
                (Some((l, [fill, wall, project, total, gather, scatter])), Some(im)) => {
                    Some(interface::ImDevice::new(
                        &ctx_im,
                        l,
                        fill,
                        wall,
                        project,
                        total,
                        gather,
                        scatter,
                        im,
                        grid.rows() * mx,
                        nv,
                    ))
                }
                _ => None,
            },
        })
    }

    /// The device this solver runs on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }
    /// f64 or f32 kernels.
    pub fn precision(&self) -> Precision {
        self.ctx.precision
    }
    /// Set when the kernels run in f32 (for the log and `summary.json`).
    pub fn warning(&self) -> Option<&str> {
        self.ctx.warning.as_deref()
    }
    pub fn time(&self) -> f64 {
        self.time
    }
    pub fn steps(&self) -> u64 {
        self.steps
    }
    /// Impulse of the domain boundaries on the gas since the start (N s), as the CPU's
    /// `Fluid::boundary_impulse`.
    pub fn boundary_impulse(&self) -> [f64; 3] {
        self.impulse
    }
    /// Work of the domain boundaries on the gas since the start (J), as the CPU's
    /// `Fluid::boundary_work`.
    pub fn boundary_work(&self) -> f64 {
        self.work
    }

    /// Start a window of the immersed coupling with new particle data: what
    /// `Immersed::set_particles` does on the CPU, with the state on the device. Only the
    /// cells the classification can read or change cross (gathered into `f.cons`, updated by
    /// the CPU code, scattered back); `f` must be the model this solver was built from.
    pub fn set_particles(
        &mut self,
        im: &mut Immersed,
        f: &mut Fluid,
        pos: &[f64],
        vel: &[f64],
        vol: &[f64],
    ) -> Result<(), SolverError> {
        let group0 = (&self.bind, self.stage_off[0]);
        let Some(dev) = self.im.as_mut() else {
            return Err(SolverError::Other(
                "GPU set_particles: this solver was built without an immersed interface".into(),
            ));
        };
        if f.cons.len() != self.len {
            return Err(SolverError::Other(format!(
                "GPU set_particles: the model has {} values, the device grid {}",
                f.cons.len(),
                self.len
            )));
        }
        dev.set_particles(&self.ctx, group0, self.max_wg, im, f, pos, vel, vol)
            .map_err(gpu_err)
    }

    /// The window's impulse on each particle (`im.impulse`) and the running totals
    /// (`im.total_impulse`, `im.wall_mass`) from the device, after `advance_to`.
    pub fn read_impulses(&self, im: &mut Immersed) -> Result<(), SolverError> {
        match &self.im {
            Some(dev) => dev.impulses(&self.ctx, im).map_err(gpu_err),
            None => Ok(()),
        }
    }

    /// Replace the device state by `f`'s conserved state, time, step count and impulse
    /// (e.g. after `load_state` on the CPU side). The grid must be the one built with.
    pub fn upload(&mut self, f: &Fluid) -> Result<(), SolverError> {
        if f.cons.len() != self.len {
            return Err(SolverError::Other(format!(
                "GPU upload: {} values, the device grid has {}",
                f.cons.len(),
                self.len
            )));
        }
        self.ctx
            .upload(&self.cons, 0, &reals_to_bytes(self.ctx.precision, &f.cons));
        self.time = f.time;
        self.steps = f.steps;
        self.impulse = f.boundary_impulse;
        self.work = f.boundary_work;
        Ok(())
    }

    /// Copy the device state into `f` (conserved variables, time, step count, boundary
    /// impulse); `f` must be the model this solver was built from.
    pub fn download(&self, f: &mut Fluid) -> Result<(), SolverError> {
        if f.cons.len() != self.len {
            return Err(SolverError::Other(format!(
                "GPU download: the model has {} values, the device grid {}",
                f.cons.len(),
                self.len
            )));
        }
        let p = self.ctx.precision;
        let b = self
            .ctx
            .read(&self.cons, 0, (self.len * p.bytes()) as u64)
            .map_err(gpu_err)?;
        bytes_to_reals(p, &b, &mut f.cons).map_err(gpu_err)?;
        f.time = self.time;
        f.steps = self.steps;
        f.boundary_impulse = self.impulse;
        f.boundary_work = self.work;
        f.prim_valid = false;
        Ok(())
    }

    /// Advance to `t1` by CFL steps, the last one shortened to land on t1 exactly (as
    /// `EulerSolver::advance_to`); returns the number of steps.
    pub fn advance_to(&mut self, t1: f64) -> Result<u64, SolverError> {
        if !(self.time < t1) {
            return Ok(0);
        }
        self.run(0, t1, u64::MAX)
    }

    /// Exactly `n` steps of at most `dt_max` each (benchmarks; no landing on a time).
    pub fn steps_n(&mut self, n: u64, dt_max: f64) -> Result<u64, SolverError> {
        if n == 0 {
            return Ok(0);
        }
        self.run(1, dt_max, n)
    }

    /// The CFL-limited step of the current device state (as `step::stable_dt`): the wave-rate
    /// reduction on the device, one real back. Errors when a cell is inadmissible.
    pub fn stable_dt(&self) -> Result<f64, SolverError> {
        self.arm(1, f64::INFINITY, 1);
        let plan = [
            Planned {
                kernel: Kernel::PrimRate,
                stage: 0,
                dims: self.dims(self.cells, RWG),
            },
            Planned {
                kernel: Kernel::ReduceDt,
                stage: 0,
                dims: (1, 1),
            },
        ];
        let (ctrl, st) = self.submit_read(self.encode_steps(&plan, 1))?;
        match st[3] {
            0 => Ok(ctrl[2]),
            1 => Err(self.bad_cell(st[4], 0)),
            _ => Err(SolverError::Diverged {
                time: self.time,
                reason: format!(
                    "no finite stable time step (largest wave rate {:e} 1/s, on the GPU)",
                    ctrl[3]
                ),
            }),
        }
    }

    fn dims(&self, threads: u32, wg: u32) -> (u32, u32) {
        dispatch_dims(threads.div_ceil(wg), self.max_wg)
    }

    /// Mass, momentum, kinetic and internal energy and the largest pressure of the device
    /// state, as `diagnostics::totals` computes them (per-row sums on the device, rows
    /// summed in order on the host: 10 reals per row cross, not the field).
    pub fn totals(&self) -> Result<Totals, SolverError> {
        let p = self.ctx.precision;
        let nrows = self.grid.n[1] * self.grid.n[2];
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("totals"),
            });
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipes.row_totals);
            pass.set_bind_group(0, &self.bind, &[self.stage_off[0]]);
            if let Some(im) = &self.im {
                pass.set_bind_group(1, &im.bind, &[]);
            }
            let (x, y) = dispatch_dims((nrows as u32).div_ceil(WG), self.max_wg);
            pass.dispatch_workgroups(x, y, 1);
        }
        self.ctx
            .checked("GPU totals", || self.ctx.queue.submit(Some(enc.finish())))
            .map_err(gpu_err)?;
        let b = self
            .ctx
            .read(&self.flux, 0, (10 * nrows * p.bytes()) as u64)
            .map_err(gpu_err)?;
        let mut rows = vec![0.0; 10 * nrows];
        bytes_to_reals(p, &b, &mut rows).map_err(gpu_err)?;
        let mut t = Totals::default();
        for row in rows.chunks_exact(10) {
            t.mass += row[0];
            for d in 0..3 {
                t.momentum[d] += row[1 + d];
            }
            t.kinetic += row[4];
            t.internal += row[5];
            t.max_pressure = t.max_pressure.max(row[6]);
            t.momentum_gross += row[7];
            // a row of solid cells only reports the kernel's 1e30: no gas cell
            if row[8] < 1.0e29 {
                t.min_pressure = t.min_pressure.min(row[8]);
                t.min_density = t.min_density.min(row[9]);
            }
        }
        Ok(t)
    }

    /// [ρ, p, u, v, w] of the cells (row, x index; ghost-inclusive, as `Probe`), read from the
    /// device one cell at a time (as `diagnostics::cell_state`).
    pub fn cell_states(&self, cells: &[(usize, usize)]) -> Result<Vec<[f64; 5]>, SolverError> {
        let p = self.ctx.precision;
        let mx = self.mx;
        let mut out = Vec::with_capacity(cells.len());
        for &(r, i) in cells {
            if r >= self.grid.rows() || i >= mx {
                return Err(SolverError::Other(format!(
                    "cell (row {r}, x index {i}) is outside the device grid"
                )));
            }
            // the nv values of a cell are mx apart: read the span and pick them
            let nv = self.nv;
            let first = (r * nv * mx + i) * p.bytes();
            let span = ((nv - 1) * mx + 1) * p.bytes();
            let b = self
                .ctx
                .read(&self.cons, first as u64, span as u64)
                .map_err(gpu_err)?;
            let mut vals = vec![0.0; (nv - 1) * mx + 1];
            bytes_to_reals(p, &b, &mut vals).map_err(gpu_err)?;
            let c: Vec<f64> = (0..nv).map(|v| vals[v * mx]).collect();
            let (rho, vel, pr, _) = crate::diagnostics::cell_prim_of(&self.phases, &c);
            out.push([rho, pr, vel[0], vel[1], vel[2]]);
        }
        Ok(out)
    }

    /// The volume fraction of `material` in each of `cells` ((row, x index), ghost-inclusive),
    /// from the device's conserved state: each row the cells lie in is read once, whole (one
    /// read back per row: a line along x costs one, a line across the rows one per row).
    pub fn volume_fractions(
        &self,
        cells: &[(usize, usize)],
        material: usize,
    ) -> Result<Vec<f64>, SolverError> {
        let p = self.ctx.precision;
        let (mx, nv) = (self.mx, self.nv);
        let block = nv * mx;
        let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
        let mut out = Vec::with_capacity(cells.len());
        let mut c = vec![0.0; nv];
        for &(r, i) in cells {
            if r >= self.grid.rows() || i >= mx {
                return Err(SolverError::Other(format!(
                    "cell (row {r}, x index {i}) is outside the device grid"
                )));
            }
            // a line's cells come in order along it: mostly the row of the cell before
            let last = rows.len().wrapping_sub(1);
            let known = if rows.last().is_some_and(|(q, _)| *q == r) {
                Some(last)
            } else {
                rows.iter().position(|(q, _)| *q == r)
            };
            let k = match known {
                Some(k) => k,
                None => {
                    let b = self
                        .ctx
                        .read(
                            &self.cons,
                            (r * block * p.bytes()) as u64,
                            (block * p.bytes()) as u64,
                        )
                        .map_err(gpu_err)?;
                    let mut vals = vec![0.0; block];
                    bytes_to_reals(p, &b, &mut vals).map_err(gpu_err)?;
                    rows.push((r, vals));
                    rows.len() - 1
                }
            };
            for (v, x) in c.iter_mut().enumerate() {
                *x = rows[k].1[v * mx + i];
            }
            out.push(crate::diagnostics::cell_prim_of(&self.phases, &c).3[material]);
        }
        Ok(out)
    }

    /// Load the control words for a run: clock, end time (mode 0) or step cap and step
    /// target (mode 1), running totals; no error, the step counters at zero.
    fn arm(&self, mode: u32, t_or_cap: f64, target: u64) {
        let p = self.ctx.precision;
        let mut ctrl = [0.0; NCTRL];
        ctrl[0] = self.time;
        ctrl[1] = t_or_cap;
        ctrl[4..7].copy_from_slice(&self.impulse);
        ctrl[7] = self.work;
        let mut st = [0u32; NST];
        st[0] = 1;
        st[4] = u32::MAX;
        st[6] = mode;
        st[7] = target.min(u32::MAX as u64) as u32;
        self.ctx.upload(&self.red, 0, &reals_to_bytes(p, &ctrl));
        self.ctx.upload(
            &self.st,
            0,
            &st.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>(),
        );
    }

    /// Take the device's clock, totals and substep count (since `arm`, on top of `steps0`)
    /// into the host mirror; the device's error, if it stopped on one.
    fn absorb(
        &mut self,
        ctrl: &[f64; NCTRL],
        st: &[u32; NST],
        steps0: u64,
    ) -> Result<(), SolverError> {
        self.time = ctrl[0];
        self.impulse = [ctrl[4], ctrl[5], ctrl[6]];
        self.work = ctrl[7];
        self.steps = steps0 + st[2] as u64;
        match st[3] {
            0 => Ok(()),
            1 => Err(self.bad_cell(st[4], st[5])),
            _ => Err(SolverError::Diverged {
                time: self.time,
                reason: format!(
                    "no finite stable time step (largest wave rate {:e} 1/s, on the GPU)",
                    ctrl[3]
                ),
            }),
        }
    }

    fn run(&mut self, mode: u32, t_or_cap: f64, target: u64) -> Result<u64, SolverError> {
        self.arm(mode, t_or_cap, target);
        let steps0 = self.steps;
        let mut done = 0u64;
        loop {
            let want = if mode == 1 {
                target - done
            } else if self.last_dt > 0.0 {
                ((t_or_cap - self.time) / self.last_dt).ceil() as u64 + 1
            } else {
                1
            };
            let batch = want.clamp(1, MAX_BATCH);
            let (ctrl, st) = self.batch(batch)?;
            let sub = st[2] as u64;
            let t_prev = self.time;
            self.absorb(&ctrl, &st, steps0)?;
            if sub > done {
                self.last_dt = (self.time - t_prev) / (sub - done) as f64;
            }
            done = sub;
            if st[0] == 0 {
                if mode == 0 {
                    // Landed on t1. The device holds time in its own precision: in f32 it
                    // landed on t1 rounded to f32, so the host keeps the exact window end.
                    self.time = t_or_cap;
                }
                return Ok(done);
            }
            if done > self.max_steps {
                return Err(SolverError::Diverged {
                    time: self.time,
                    reason: format!(
                        "more than {} steps in one window (max_steps_per_window)",
                        self.max_steps
                    ),
                });
            }
        }
    }

    /// The dispatches of one step in order (the immersed kernels when the interface has
    /// occupied cells this window).
    fn plan(&self) -> Vec<Planned> {
        let active = self.im.as_ref().filter(|im| im.ncells > 0);
        let mut v = Vec::with_capacity(4 + 3 * (8 + 2 * self.nd));
        let at = |kernel, stage, threads, wg| Planned {
            kernel,
            stage,
            dims: self.dims(threads, wg),
        };
        v.push(at(Kernel::PrimRate, 0, self.cells, RWG));
        v.push(at(Kernel::ReduceDt, 0, 1, 1));
        for s in 0..3 {
            if s > 0 {
                v.push(at(Kernel::PrimOnly, s, self.cells, RWG));
            }
            if let Some(im) = active {
                v.push(at(Kernel::ImFill, s, im.ncells, WG));
            }
            for d in 0..self.nd {
                v.push(at(Kernel::Ghost(d), s, self.ghost_n[d], WG));
            }
            for d in 0..self.nd {
                v.push(at(Kernel::Flux(d), s, self.face_n[d], WG));
            }
            if let Some(im) = active.filter(|im| im.nwalls > 0) {
                v.push(at(Kernel::ImWall, s, im.nwalls, WG));
            }
            v.push(Planned {
                kernel: Kernel::Impulse,
                stage: s,
                dims: (4, self.iparts),
            });
            v.push(at(Kernel::ImpulseSum, s, 1, 1));
            v.push(at(Kernel::Update, s, self.cells, WG));
            if let Some(im) = active {
                v.push(at(Kernel::ImProject, s, im.ncells, WG));
                v.push(at(Kernel::ImTotal, s, 1, 1));
            }
        }
        v.push(at(Kernel::Finish, 0, 1, 1));
        v
    }

    fn pipeline(&self, k: Kernel) -> &wgpu::ComputePipeline {
        let im = || {
            self.im
                .as_ref()
                .expect("immersed kernels planned without an interface")
        };
        match k {
            Kernel::PrimRate => &self.pipes.prim_rate,
            Kernel::PrimOnly => &self.pipes.prim_only,
            Kernel::ReduceDt => &self.pipes.reduce_dt,
            Kernel::Ghost(d) => &self.pipes.ghost[d],
            Kernel::Flux(d) => &self.pipes.flux[d],
            Kernel::Impulse => &self.pipes.impulse,
            Kernel::ImpulseSum => &self.pipes.impulse_sum,
            Kernel::Update => &self.pipes.update,
            Kernel::Finish => &self.pipes.finish,
            Kernel::ImFill => &im().fill,
            Kernel::ImWall => &im().wall,
            Kernel::ImProject => &im().project,
            Kernel::ImTotal => &im().total,
        }
    }

    /// The bytes a kernel must move at the least (each value it reads or writes once, as if
    /// every neighbour's value came from cache): the numerator of its achieved bandwidth.
    fn compulsory_bytes(&self, d: &Planned) -> u64 {
        let rb = self.ctx.precision.bytes() as u64;
        let cells = self.cells as u64;
        let nd = self.nd as u64;
        let nv = self.nv as u64;
        let nf = if nv == 5 { nv } else { nv + 1 };
        let vals = match d.kernel {
            // nv conserved in, nv primitives out
            Kernel::PrimRate | Kernel::PrimOnly => 2 * nv * cells,
            // one value read and one written per thread
            Kernel::Ghost(g) => 2 * self.ghost_n[g] as u64,
            // nv primitives of each cell in, nf fluxes of each face out
            Kernel::Flux(f) => nv * cells + nf * self.face_n[f] as u64,
            // fluxes in (with the face velocities for the volume fractions), U (and U0) in,
            // U out (stage 0 writes U0 instead of reading it)
            Kernel::Update => (nf * nd + 3 * nv) * cells,
            Kernel::Impulse => {
                let faces: u64 = (0..self.nd)
                    .map(|a| 2 * self.face_n[a] as u64 / (self.grid.n[a] as u64 + 1))
                    .sum();
                4 * faces
            }
            Kernel::ReduceDt => NCTRL as u64 + cells.div_ceil(RWG as u64),
            _ => 0,
        };
        vals * rb
    }

    /// Encode `k` steps in one submission; return the control reals and status words.
    ///
    /// The steps go to the device in command buffers of [`CHUNK`] steps, each submitted as
    /// soon as it is encoded, so the device runs one while the host encodes the next; only
    /// the last one waits for the control words.
    fn batch(&self, k: u64) -> Result<([f64; NCTRL], [u32; NST]), SolverError> {
        let plan = self.plan();
        let mut left = k;
        loop {
            let n = left.min(CHUNK);
            left -= n;
            let enc = self.encode_steps(&plan, n);
            if left == 0 {
                return self.submit_read(enc);
            }
            self.ctx.queue.submit(Some(enc.finish()));
        }
    }

    /// `n` steps of `plan` in one compute pass. The interface's group is bound once and the
    /// solver's group again only where the RK stage (its uniform offset) changes: wgpu keeps
    /// bindings across pipelines of one layout, and every binding call costs host time.
    fn encode_steps(&self, plan: &[Planned], n: u64) -> wgpu::CommandEncoder {
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("euler steps"),
            });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("euler"),
                timestamp_writes: None,
            });
            if let Some(im) = &self.im {
                pass.set_bind_group(1, &im.bind, &[]);
            }
            let mut stage = usize::MAX;
            for _ in 0..n {
                for d in plan {
                    pass.set_pipeline(self.pipeline(d.kernel));
                    if d.stage != stage {
                        pass.set_bind_group(0, &self.bind, &[self.stage_off[d.stage]]);
                        stage = d.stage;
                    }
                    pass.dispatch_workgroups(d.dims.0, d.dims.1, 1);
                }
            }
        }
        enc
    }

    /// Time each kernel of `steps` steps (after one untimed step) on the device's clock, one
    /// compute pass per dispatch, and advance the state by those steps (CFL steps, no landing
    /// on a time). `None` when the adapter has no timestamp queries. The passes add a little
    /// per dispatch that the batched steps do not pay, so the sum of the rows is an upper
    /// bound of the step's device time.
    pub fn profile(&mut self, steps: u32) -> Result<Option<Vec<KernelProfile>>, SolverError> {
        let plan = self.plan();
        let per_step = plan.len() as u32;
        let steps = steps.clamp(1, mechanics::gpu::TIMER_SLOTS / per_step);
        let Some(timer) = self.ctx.timer(steps * per_step) else {
            return Ok(None);
        };
        self.steps_n(1, f64::INFINITY)?;
        self.arm(1, f64::INFINITY, steps as u64);
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("euler profile"),
            });
        let mut slot = 0;
        for _ in 0..steps {
            for d in &plan {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(d.kernel.name()),
                    timestamp_writes: Some(timer.writes(slot)),
                });
                pass.set_pipeline(self.pipeline(d.kernel));
                pass.set_bind_group(0, &self.bind, &[self.stage_off[d.stage]]);
                if let Some(im) = &self.im {
                    pass.set_bind_group(1, &im.bind, &[]);
                }
                pass.dispatch_workgroups(d.dims.0, d.dims.1, 1);
                slot += 1;
            }
        }
        timer.resolve(&mut enc, slot);
        let (ctrl, st) = self.submit_read(enc)?;
        let secs = timer.read(&self.ctx, slot).map_err(gpu_err)?;
        self.absorb(&ctrl, &st, self.steps)?;
        let mut rows: Vec<KernelProfile> = Vec::new();
        for (i, d) in plan.iter().cycle().take(slot as usize).enumerate() {
            let name = d.kernel.name();
            let bytes = self.compulsory_bytes(d);
            let row = match rows.iter_mut().find(|r| r.kernel == name) {
                Some(r) => r,
                None => {
                    rows.push(KernelProfile {
                        kernel: name,
                        dispatches: 0,
                        seconds: 0.0,
                        bytes: 0,
                    });
                    rows.last_mut().expect("just pushed")
                }
            };
            row.seconds += secs[i] / steps as f64;
            row.bytes += bytes;
            row.dispatches += 1;
        }
        for r in &mut rows {
            r.bytes /= steps as u64;
            r.dispatches /= steps;
        }
        Ok(Some(rows))
    }

    /// Copy the control words behind `enc`'s work, submit, wait and read them.
    fn submit_read(
        &self,
        mut enc: wgpu::CommandEncoder,
    ) -> Result<([f64; NCTRL], [u32; NST]), SolverError> {
        let ctx = &self.ctx;
        let p = ctx.precision;
        let rb = p.bytes();
        enc.copy_buffer_to_buffer(&self.red, 0, &self.staging, 0, (NCTRL * rb) as u64);
        enc.copy_buffer_to_buffer(
            &self.st,
            0,
            &self.staging,
            (NCTRL * rb) as u64,
            (NST * 4) as u64,
        );
        ctx.submit_and_map(enc, &self.staging).map_err(gpu_err)?;
        let mut ctrl = [0.0; NCTRL];
        let mut st = [0u32; NST];
        {
            let view = self
                .staging
                .get_mapped_range(..)
                .map_err(|e| SolverError::Other(format!("GPU control readback: {e}")))?;
            bytes_to_reals(p, &view[..NCTRL * rb], &mut ctrl).map_err(gpu_err)?;
            for (w, c) in st.iter_mut().zip(view[NCTRL * rb..].chunks_exact(4)) {
                *w = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            }
        }
        self.staging.unmap();
        Ok((ctrl, st))
    }

    /// The error for an inadmissible cell found on the device (flat index of its first
    /// variable), with its conserved state read back.
    fn bad_cell(&self, flat: u32, stage: u32) -> SolverError {
        let flat = flat as usize;
        let p = self.ctx.precision;
        let mx = self.mx;
        let grid = &self.grid;
        let nv = self.nv;
        let (r, i) = (flat / (nv * mx), flat % (nv * mx));
        let mut c = vec![f64::NAN; nv];
        if let Ok(b) = self.ctx.read(
            &self.cons,
            (r * nv * mx * p.bytes()) as u64,
            (nv * mx * p.bytes()) as u64,
        ) {
            let mut row = vec![0.0; nv * mx];
            if bytes_to_reals(p, &b, &mut row).is_ok() {
                for (v, x) in c.iter_mut().enumerate() {
                    *x = row[v * mx + i];
                }
            }
        }
        // step.rs prim_row's diagnosis of the same conserved state (the pressure where it
        // finds nothing wrong: the device's arithmetic rejected a state at the edge)
        let nm = self.phases.len();
        let (var, val) = crate::step::diagnose(&self.phases, &c).unwrap_or_else(|| {
            let (_, _, p, _) = crate::diagnostics::cell_prim_of(&self.phases, &c);
            (nm + 3, p)
        });
        let (j, k) = grid.jk(r);
        let x = grid.centre(i, j, k);
        SolverError::Diverged {
            time: self.time,
            reason: format!(
                "cell ({}, {}, {}) at x = ({:.6e}, {:.6e}, {:.6e}) m: {} = {val:e} (RK stage {}, on the GPU)",
                i - grid.g[0],
                j - grid.g[1],
                k - grid.g[2],
                x[0],
                x[1],
                x[2],
                crate::step::prim_name(nm, var),
                stage + 1
            ),
        }
    }
}
