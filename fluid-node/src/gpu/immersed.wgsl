// Immersed-particle operations of the fluid step on the device (seed 002
// §3, eq. 31–35), appended to euler.wgsl when the model has an [immersed] interface. They
// mirror fluid-node/src/immersed.rs operation by operation:
//   im_fill    fill_solid_prims: solid cells next to the gas take the mean primitive state of
//              their gas face neighbours (eq. 32) and the particle velocity (eq. 31);
//   im_wall    wall_fluxes: HLLC flux of each interface/solid face against the mirror state
//              moving with the interface velocity; the momentum it carries (weighted by the
//              stage's flux weight · dt) is stored per wall;
//   im_project project: solid cells keep their frozen state, interface cells are reset to
//              ρ v_ib keeping ρe; each occupied cell accumulates its particles' impulse (equal
//              shares, eq. 34; stage weights 1/6, 2/3, 1, eq. 35) in the CPU's order (its walls
//              in list order, then its projection) — every particle of a cell receives the same
//              sequence of additions, so one accumulator per cell is the per-particle impulse;
//   im_total   the running totals (impulse to the particles, mass through moving walls) in
//              the CPU's summation order, one thread;
//   im_gather / im_scatter  the conserved state of a compact list of cells to / from the
//              exchange area (the per-window classification and refill run on the host).
// The host builds the tables once per window (classification is per window, seed 002 §3).

// u32 tables: header (see immersed.rs of gpu/), then the arrays at the offsets it names
@group(1) @binding(0) var<storage, read> imu: array<u32>;
// reals: [0..3] total impulse, [3] wall mass, then the arrays at the header's offsets
@group(1) @binding(1) var<storage, read_write> imr: array<real>;

const IM_SOLID: u32 = 2u;
const IM_INTERFACE: u32 = 1u;

// the solid mask after the 32-word header (diagnostics.rs totals skips solid cells)
fn is_solid_cell(c: u32) -> bool { return imu[32u + c] == 1u; }
fn im_ncells() -> u32 { return imu[0]; }
fn im_nwalls() -> u32 { return imu[1]; }
fn im_nx() -> u32 { return imu[2]; }
fn im_cell(ci: u32) -> u32 { return imu[imu[4] + ci]; }
fn im_kind(ci: u32) -> u32 { return imu[imu[5] + ci]; }
fn im_count(ci: u32) -> u32 { return imu[imu[6] + ci]; }
fn im_woff(ci: u32) -> u32 { return imu[imu[7] + ci]; }
fn im_nbc(ci: u32) -> u32 { return imu[imu[8] + ci]; }
fn im_nb(ci: u32, k: u32) -> u32 { return imu[imu[9] + 6u * ci + k]; }
// wall w: [direction, gas cell, left cell, gas is left, solid cell index, gas cell index]
fn im_wall_u(w: u32, k: u32) -> u32 { return imu[imu[10] + 6u * w + k]; }
fn im_xcell(k: u32) -> u32 { return imu[imu[11] + k]; }
fn r_imp() -> u32 { return imu[12]; }
fn r_vel() -> u32 { return imu[13]; }
fn r_wj() -> u32 { return imu[14]; }
fn r_wm() -> u32 { return imu[15]; }
fn r_rem() -> u32 { return imu[16]; }
fn r_xch() -> u32 { return imu[17]; }

// projection weight of RK stage s (seed 002 eq. 35), from the real parameters
fn proj_w(s: u32) -> real { return pr[45u + s]; }

// first variable of flat cell c = row · mx + i in the row-blocked layout
fn cbase(c: u32) -> u32 { return at(c / mx(), 0u, c % mx()); }

// immersed.rs fill_solid_prims
@compute @workgroup_size(WG)
fn im_fill(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let ci = lin(gid, nwg, WG);
    if ci >= im_ncells() || !running() || im_kind(ci) != IM_SOLID {
        return;
    }
    let w = mx();
    let b = cbase(im_cell(ci));
    let nb = im_nbc(ci);
    if nb > 0u {
        var acc: array<real, NV>;
        for (var v = 0u; v < NV; v++) {
            acc[v] = real(0.0);
        }
        var cnt = real(0.0);
        for (var k = 0u; k < nb; k++) {
            let o = cbase(im_nb(ci, k));
            for (var v = 0u; v < NV; v++) {
                acc[v] += prim[o + v * w];
            }
            cnt += real(1.0);
        }
        for (var v = 0u; v < NV; v++) {
            prim[b + v * w] = acc[v] / cnt;
        }
    }
    let vo = r_vel() + 3u * ci;
    for (var d = 0u; d < 3u; d++) {
        prim[b + (NM + d) * w] = imr[vo + d];
    }
}

// immersed.rs wall_fluxes, one wall face per thread
@compute @workgroup_size(WG)
fn im_wall(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let wi = lin(gid, nwg, WG);
    if wi >= im_nwalls() || !running() {
        return;
    }
    let d = im_wall_u(wi, 0u);
    let gas = im_wall_u(wi, 1u);
    let left = im_wall_u(wi, 2u);
    let gas_left = im_wall_u(wi, 3u) == 1u;
    let gci = im_wall_u(wi, 5u);
    let w = mx();
    let bg = cbase(gas);
    var q: array<real, NV>;
    for (var v = 0u; v < NV; v++) {
        q[v] = prim[bg + v * w];
    }
    var wall = real(0.0);
    if gci != 0xffffffffu {
        wall = imr[r_vel() + 3u * gci + d];
    }
    var mq = q;
    mq[NM + d] = real(2.0) * wall - q[NM + d];
    let fa = face(q);
    let fb = face(mq);
    var fl: array<real, NF>;
    if fa.ok && fb.ok {
        if gas_left {
            fl = hllc(fa, fb, d);
        } else {
            fl = hllc(fb, fa, d);
        }
    } else {
        fl = nan_flux();
    }
    let fo = d * fsize() + fat(left / w, 0u, left % w);
    for (var v = 0u; v < NF; v++) {
        flux[fo + v * w] = fl[v];
    }
    var sign = real(-1.0);
    if gas_left {
        sign = real(1.0);
    }
    let dtw = stg.w * red[2];
    let ar = area(d);
    let jo = r_wj() + 3u * wi;
    for (var c = 0u; c < 3u; c++) {
        imr[jo + c] = sign * fl[NM + c] * ar * dtw;
    }
    var mflux = real(0.0);
    for (var k = 0u; k < NM; k++) {
        mflux += fl[k];
    }
    imr[r_wm() + wi] = sign * mflux * ar * dtw;
}

// immersed.rs project (and project_cell), one occupied cell per thread
@compute @workgroup_size(WG)
fn im_project(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let ci = lin(gid, nwg, WG);
    if ci >= im_ncells() || !running() {
        return;
    }
    let w = mx();
    let b = cbase(im_cell(ci));
    let io = r_imp() + 3u * ci;
    var imp = array<real, 3>(imr[io], imr[io + 1u], imr[io + 2u]);
    let cnt = real(im_count(ci));
    if im_kind(ci) == IM_SOLID {
        for (var v = 0u; v < NV; v++) {
            cons[b + v * w] = cons0[b + v * w];
        }
        // this stage's wall momenta into the solid cell, in wall order
        let share = real(1.0) / cnt;
        for (var k = im_woff(ci); k < im_woff(ci + 1u); k++) {
            let jo = r_wj() + 3u * k;
            for (var c = 0u; c < 3u; c++) {
                imp[c] += share * imr[jo + c];
            }
        }
    } else {
        let vo = r_vel() + 3u * ci;
        let vel = array<real, 3>(imr[vo], imr[vo + 1u], imr[vo + 2u]);
        let vol = cell_volume();
        var rho = real(0.0);
        for (var k = 0u; k < NM; k++) {
            rho += cons[b + k * w];
        }
        let m = array<real, 3>(cons[b + NM * w], cons[b + (NM + 1u) * w], cons[b + (NM + 2u) * w]);
        let ke_old = real(0.5) * (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) / rho;
        let ke_new = real(0.5) * rho * (vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]);
        let ro = r_rem() + 3u * ci;
        let share = proj_w(stg.s) / cnt;
        for (var c = 0u; c < 3u; c++) {
            let mn = rho * vel[c];
            let removed = vol * (m[c] - mn);
            cons[b + (NM + c) * w] = mn;
            imr[ro + c] = removed;
            imp[c] += share * removed;
        }
        cons[b + (NM + 3u) * w] += ke_new - ke_old;
    }
    for (var c = 0u; c < 3u; c++) {
        imr[io + c] = imp[c];
    }
}

// the running totals in the CPU's order: every wall (impulse, then mass), then every
// interface cell's weighted projection
@compute @workgroup_size(1)
fn im_total() {
    if !running() {
        return;
    }
    var tot = array<real, 3>(imr[0], imr[1], imr[2]);
    var wm = imr[3];
    for (var k = 0u; k < im_nwalls(); k++) {
        let jo = r_wj() + 3u * k;
        for (var c = 0u; c < 3u; c++) {
            tot[c] += imr[jo + c];
        }
        wm -= imr[r_wm() + k];
    }
    let pw = proj_w(stg.s);
    for (var ci = 0u; ci < im_ncells(); ci++) {
        if im_kind(ci) == IM_INTERFACE {
            let ro = r_rem() + 3u * ci;
            for (var c = 0u; c < 3u; c++) {
                tot[c] += pw * imr[ro + c];
            }
        }
    }
    for (var c = 0u; c < 3u; c++) {
        imr[c] = tot[c];
    }
    imr[3] = wm;
}

// the conserved state of the listed cells into the exchange area (NV reals per cell)
@compute @workgroup_size(WG)
fn im_gather(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = lin(gid, nwg, WG);
    if k >= im_nx() {
        return;
    }
    let b = cbase(im_xcell(k));
    for (var v = 0u; v < NV; v++) {
        imr[r_xch() + NV * k + v] = cons[b + v * mx()];
    }
}

// ... and back
@compute @workgroup_size(WG)
fn im_scatter(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = lin(gid, nwg, WG);
    if k >= im_nx() {
        return;
    }
    let b = cbase(im_xcell(k));
    for (var v = 0u; v < NV; v++) {
        cons[b + v * mx()] = imr[r_xch() + NV * k + v];
    }
}
