//! The immersed coupling (seed 002 §3, eq. 31–35; docs/architecture.md "immersed") with the fluid
//! state on the device. The per-stage work — solid-cell primitives
//! (eq. 32), moving-wall fluxes, projection of interface cells onto the particle velocity
//! (eq. 31, 33) and the particle impulses (eq. 34–35) — runs in `immersed.wgsl` inside the
//! step batches. The per-window work — classification of cells, refill of cells the solid
//! leaves (eq. 32), the window-start projection — is the CPU code of `crate::immersed`, run on
//! a host copy of only the cells it can touch: the cells occupied before and after the
//! update and their face neighbours (a compact list, gathered from and scattered back to the
//! device), never the whole grid. At the window end only the per-cell impulses and four
//! running totals come back.

use crate::immersed::{Immersed, SOLID};
use crate::model::Fluid;
use mechanics::gpu::{GpuContext, GpuError, bytes_to_reals, reals_to_bytes, u32_bytes};
use std::sync::Arc;

/// u32 header words in the `imu` buffer; then one word per cell of the grid (ghosts
/// included), 1 for a solid cell (the totals skip them, as `diagnostics::totals`); then the
/// tables.
pub(super) const HDR: usize = 32;
/// Reals before the tables in the `imr` buffer (total impulse x, y, z; wall mass).
pub(super) const RHDR: usize = 4;
/// "No such cell" in the wall table.
const NONE32: u32 = u32::MAX;

/// Device buffers and pipelines of the immersed kernels.
pub(super) struct ImDevice {
    pub bgl: wgpu::BindGroupLayout,
    pub fill: wgpu::ComputePipeline,
    pub wall: wgpu::ComputePipeline,
    pub project: wgpu::ComputePipeline,
    pub total: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    imu: wgpu::Buffer,
    imr: wgpu::Buffer,
    /// Capacities in u32 words / reals.
    cap_u: usize,
    cap_r: usize,
    pub bind: wgpu::BindGroup,
    /// Cells of the grid (ghosts included) and the solid mask as on the device.
    gcells: usize,
    mask: Vec<u32>,
    /// Conserved values per cell (2·NM + 3).
    nv: usize,
    /// Occupied cells, wall faces of the current window.
    pub ncells: u32,
    pub nwalls: u32,
    /// Host scratch, kept between windows (no allocation once large enough).
    xcells: Vec<u32>,
    tab_u: Vec<u32>,
    tab_r: Vec<f64>,
}

/// The bind group layout of the immersed tables (group 1).
pub(super) fn layout(ctx: &GpuContext) -> wgpu::BindGroupLayout {
    use mechanics::gpu::BufferBinding::{Read, ReadWrite};
    ctx.bind_layout("immersed", &[Read, ReadWrite])
}

fn bind(
    ctx: &GpuContext,
    bgl: &wgpu::BindGroupLayout,
    imu: &wgpu::Buffer,
    imr: &wgpu::Buffer,
) -> wgpu::BindGroup {
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("immersed"),
        layout: bgl,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: imu.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: imr.as_entire_binding(),
            },
        ],
    })
}

/// Offsets of the tables for `nc` occupied cells, `nw` wall faces, `nx` exchanged cells of
/// `nv` conserved values: (u32 header words 4..=11, real offsets in words 12..=17, u32
/// words, reals).
fn plan(gcells: usize, nc: usize, nw: usize, nx: usize, nv: usize) -> ([usize; 14], usize, usize) {
    let mut o = [0usize; 14];
    let mut u = HDR + gcells;
    // cells, kind, count, wall offsets (nc + 1), neighbour counts, neighbours (6 each),
    // walls (6 each), exchange list
    let sizes_u = [nc, nc, nc, nc + 1, nc, 6 * nc, 6 * nw, nx];
    for (k, s) in sizes_u.iter().enumerate() {
        o[k] = u;
        u += s;
    }
    let mut r = RHDR;
    // impulses, velocities, wall momenta, wall masses, removed momenta, exchange values
    let sizes_r = [3 * nc, 3 * nc, 3 * nw, nw, 3 * nc, nv * nx];
    for (k, s) in sizes_r.iter().enumerate() {
        o[8 + k] = r;
        r += s;
    }
    (o, u, r)
}

/// Face neighbours of flat cell c (row · mx + i) inside the interior, in the order of
/// `crate::immersed`'s neighbour walk (direction by direction, lower then upper).
fn neighbours(f: &Fluid, c: usize, out: &mut Vec<usize>) {
    let grid = &f.grid;
    let mx = grid.mx();
    let (r, i) = (c / mx, c % mx);
    let (j, k) = grid.jk(r);
    let idx = [i, j, k];
    for d in 0..grid.nd {
        let step = match d {
            0 => 1,
            1 => mx,
            _ => mx * grid.m[1],
        };
        if idx[d] > grid.g[d] {
            out.push(c - step);
        }
        if idx[d] + 1 < grid.g[d] + grid.n[d] {
            out.push(c + step);
        }
    }
}

impl ImDevice {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        ctx: &GpuContext,
        bgl: wgpu::BindGroupLayout,
        fill: wgpu::ComputePipeline,
        wall: wgpu::ComputePipeline,
        project: wgpu::ComputePipeline,
        total: wgpu::ComputePipeline,
        gather: wgpu::ComputePipeline,
        scatter: wgpu::ComputePipeline,
        im: &Immersed,
        gcells: usize,
        nv: usize,
    ) -> ImDevice {
        let p = ctx.precision;
        let cap_u = HDR + gcells + 64;
        let cap_r = RHDR + 64;
        let mask: Vec<u32> = im.kind.iter().map(|&k| (k == SOLID) as u32).collect();
        let mut u0 = vec![0u32; cap_u];
        u0[HDR..HDR + mask.len()].copy_from_slice(&mask);
        let imu = ctx.storage_init("immersed u32", u32_bytes(&u0));
        let mut r0 = vec![0.0; cap_r];
        r0[..3].copy_from_slice(&im.total_impulse);
        r0[3] = im.wall_mass;
        let imr = ctx.storage_init("immersed reals", &reals_to_bytes(p, &r0));
        let bind = bind(ctx, &bgl, &imu, &imr);
        ImDevice {
            bgl,
            fill,
            wall,
            project,
            total,
            gather,
            scatter,
            imu,
            imr,
            cap_u,
            cap_r,
            bind,
            gcells,
            mask,
            nv,
            ncells: 0,
            nwalls: 0,
            xcells: Vec::new(),
            tab_u: Vec::new(),
            tab_r: Vec::new(),
        }
    }

    /// Grow the buffers to hold `nu` words and `nr` reals (the solid mask is copied over).
    fn reserve(&mut self, ctx: &GpuContext, nu: usize, nr: usize) {
        if nu <= self.cap_u && nr <= self.cap_r {
            return;
        }
        let p = ctx.precision;
        self.cap_u = self.cap_u.max(nu.next_power_of_two());
        self.cap_r = self.cap_r.max(nr.next_power_of_two());
        self.imu = ctx.storage("immersed u32", self.cap_u * 4);
        ctx.upload(&self.imu, (HDR * 4) as u64, u32_bytes(&self.mask));
        self.imr = ctx.storage("immersed reals", self.cap_r * p.bytes());
        self.bind = bind(ctx, &self.bgl, &self.imu, &self.imr);
    }

    /// One dispatch of `pipe` over `threads` (workgroups of 64) with both bind groups.
    fn run(
        &self,
        ctx: &GpuContext,
        group0: (&wgpu::BindGroup, u32),
        pipe: &wgpu::ComputePipeline,
        threads: u32,
        max_wg: u32,
    ) -> Result<(), GpuError> {
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("immersed exchange"),
            });
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipe);
            pass.set_bind_group(0, group0.0, &[group0.1]);
            pass.set_bind_group(1, &self.bind, &[]);
            let (x, y) = mechanics::gpu::dispatch_dims(threads.div_ceil(64), max_wg);
            pass.dispatch_workgroups(x, y, 1);
        }
        ctx.checked("immersed exchange", || ctx.queue.submit(Some(enc.finish())))
            .map(|_| ())
    }

    /// Start a window with new particle data (as `Immersed::set_particles` on the CPU):
    /// the cells the update can read or write are gathered from the device into `f.cons`,
    /// the CPU classification / refill / projection runs on them, they go back, and the
    /// tables of the window's device kernels are uploaded.
    #[allow(clippy::too_many_arguments)]
    pub fn set_particles(
        &mut self,
        ctx: &Arc<GpuContext>,
        group0: (&wgpu::BindGroup, u32),
        max_wg: u32,
        im: &mut Immersed,
        f: &mut Fluid,
        pos: &[f64],
        vel: &[f64],
        vol: &[f64],
    ) -> Result<(), GpuError> {
        let p = ctx.precision;
        let grid = f.grid.clone();
        let mx = grid.mx();
        // the cells occupied before and after, and their face neighbours
        let mut touched: Vec<usize> = im.cells.clone();
        let mut newc: Vec<usize> = (0..vol.len())
            .filter_map(|q| {
                grid.locate([pos[3 * q], pos[3 * q + 1], pos[3 * q + 2]])
                    .map(|[i, j, k]| grid.row(j, k) * mx + i)
            })
            .collect();
        newc.sort_unstable();
        newc.dedup();
        touched.extend_from_slice(&newc);
        let base = touched.len();
        for t in 0..base {
            let c = touched[t];
            neighbours(f, c, &mut touched);
        }
        touched.sort_unstable();
        touched.dedup();
        let nc = newc.len();
        let nw_cap = 2 * grid.nd * nc;
        let nx = touched.len();
        let (o, nu, nr) = plan(self.gcells, nc, nw_cap, nx, self.nv);
        self.reserve(ctx, nu, nr);
        self.xcells.clear();
        self.xcells.extend(touched.iter().map(|&c| c as u32));
        // header: counts, no cells or walls yet (the step kernels must not run on a
        // half-built table), the exchange list
        let mut hdr = [0u32; HDR];
        hdr[2] = nx as u32;
        for k in 0..14 {
            hdr[4 + k] = o[k] as u32;
        }
        ctx.upload(&self.imu, 0, u32_bytes(&hdr));
        ctx.upload(&self.imu, (o[7] * 4) as u64, u32_bytes(&self.xcells));
        let nv = f.nv;
        if nx > 0 {
            self.run(ctx, group0, &self.gather, nx as u32, max_wg)?;
            let b = ctx.read(
                &self.imr,
                (o[13] * p.bytes()) as u64,
                (nv * nx * p.bytes()) as u64,
            )?;
            self.tab_r.clear();
            self.tab_r.resize(nv * nx, 0.0);
            bytes_to_reals(p, &b, &mut self.tab_r)?;
            for (k, &c) in touched.iter().enumerate() {
                let (r, i) = (c / mx, c % mx);
                for v in 0..nv {
                    f.cons[(r * nv + v) * mx + i] = self.tab_r[nv * k + v];
                }
            }
        }
        // the CPU's classification, refill and window-start projection on those cells
        im.set_particles(f, pos, vel, vol);
        if im.cells.len() != nc || im.walls.len() > nw_cap {
            return Err(GpuError(format!(
                "immersed tables: {} occupied cells and {} walls, planned {nc} and at most {nw_cap}",
                im.cells.len(),
                im.walls.len()
            )));
        }
        // u32 tables
        let nw = im.walls.len();
        let tu = &mut self.tab_u;
        tu.clear();
        tu.resize(o[7], 0);
        tu[0] = nc as u32;
        tu[1] = nw as u32;
        tu[2] = nx as u32;
        for k in 0..14 {
            tu[4 + k] = o[k] as u32;
        }
        let mut nb = Vec::with_capacity(6);
        let mut wall_at = 0usize;
        for (ci, &c) in im.cells.iter().enumerate() {
            tu[o[0] + ci] = c as u32;
            tu[o[1] + ci] = im.cell_kind[ci] as u32;
            tu[o[2] + ci] = (im.off[ci + 1] - im.off[ci]) as u32;
            tu[o[3] + ci] = wall_at as u32;
            // walls are listed solid cell by solid cell, in cell order
            while wall_at < nw {
                let w = &im.walls[wall_at];
                let solid = if w.gas_left { w.right } else { w.left };
                if solid != c {
                    break;
                }
                wall_at += 1;
            }
            nb.clear();
            neighbours(f, c, &mut nb);
            let mut cnt = 0;
            for &q in &nb {
                if im.kind[q] != SOLID {
                    tu[o[5] + 6 * ci + cnt] = q as u32;
                    cnt += 1;
                }
            }
            tu[o[4] + ci] = cnt as u32;
        }
        tu[o[3] + nc] = wall_at as u32;
        if wall_at != nw {
            return Err(GpuError(format!(
                "immersed tables: {} of {nw} walls belong to a solid cell in order",
                wall_at
            )));
        }
        for (wi, w) in im.walls.iter().enumerate() {
            let gas = if w.gas_left { w.left } else { w.right };
            let solid = if w.gas_left { w.right } else { w.left };
            let gci = im.cells.binary_search(&gas).map_or(NONE32, |x| x as u32);
            let sci = im.cells.binary_search(&solid).map_or(NONE32, |x| x as u32);
            let e = o[6] + 6 * wi;
            tu[e..e + 6].copy_from_slice(&[
                w.d as u32,
                gas as u32,
                w.left as u32,
                w.gas_left as u32,
                sci,
                gci,
            ]);
        }
        // reals: running totals, zero impulses, velocities, the exchanged cells
        let tr = &mut self.tab_r;
        tr.clear();
        tr.resize(nr, 0.0);
        tr[..3].copy_from_slice(&im.total_impulse);
        tr[3] = im.wall_mass;
        for (ci, v) in im.cell_vel.iter().enumerate() {
            tr[o[9] + 3 * ci..o[9] + 3 * ci + 3].copy_from_slice(v);
        }
        for (k, &c) in touched.iter().enumerate() {
            let (r, i) = (c / mx, c % mx);
            for v in 0..nv {
                tr[o[13] + nv * k + v] = f.cons[(r * nv + v) * mx + i];
            }
        }
        ctx.upload(&self.imu, 0, u32_bytes(&tu[..HDR]));
        ctx.upload(&self.imu, (o[0] * 4) as u64, u32_bytes(&tu[o[0]..]));
        // the solid mask of the cells whose class changed (all among the touched cells)
        for &c in &touched {
            let s = (im.kind[c] == SOLID) as u32;
            if self.mask[c] != s {
                self.mask[c] = s;
                ctx.upload(&self.imu, ((HDR + c) * 4) as u64, u32_bytes(&[s]));
            }
        }
        ctx.upload(&self.imr, 0, &reals_to_bytes(p, tr));
        if nx > 0 {
            self.run(ctx, group0, &self.scatter, nx as u32, max_wg)?;
        }
        self.ncells = nc as u32;
        self.nwalls = nw as u32;
        Ok(())
    }

    /// The window's impulse on each particle and the running totals, from the device (3
    /// reals per occupied cell + 4).
    pub fn impulses(&self, ctx: &GpuContext, im: &mut Immersed) -> Result<(), GpuError> {
        let p = ctx.precision;
        let nc = self.ncells as usize;
        let n = RHDR + 3 * nc;
        let b = ctx.read(&self.imr, 0, (n * p.bytes()) as u64)?;
        let mut v = vec![0.0; n];
        bytes_to_reals(p, &b, &mut v)?;
        im.total_impulse.copy_from_slice(&v[..3]);
        im.wall_mass = v[3];
        if im.cells.len() != nc {
            return Err(GpuError(format!(
                "immersed impulses: {nc} cells on the device, {} on the host",
                im.cells.len()
            )));
        }
        for j in im.impulse.iter_mut() {
            *j = [0.0; 3];
        }
        for ci in 0..nc {
            let jc = [v[RHDR + 3 * ci], v[RHDR + 3 * ci + 1], v[RHDR + 3 * ci + 2]];
            for &q in &im.parts[im.off[ci]..im.off[ci + 1]] {
                im.impulse[q] = jc;
            }
        }
        Ok(())
    }
}
