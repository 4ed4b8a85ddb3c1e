// Single-material Euler step on the device (one ideal or stiffened gas) (seed 002 §2.3–§2.4, Fig. 4):
// primitive recovery, ghost fill, MUSCL + HLLC fluxes, SSP-RK3 stage update (seed 002 eq. 35
// weights), boundary impulse, and the CFL reduction. Every formula mirrors fluid-node's CPU
// kernels (step.rs, riemann/hllc.rs, limiter.rs, boundary.rs) operation by operation, so the
// f64 results agree with the CPU to round-off.
//
// `real` is f64 or f32: the host prepends `alias real = f64;` (or f32), and the model's
// limiter and dimension as constants (`const LIMITER: u32`, `const ND: u32`), so the driver
// compiles one limiter and only the directions the grid has.
// Layout: the CPU's row-blocked structure of arrays, value v of cell (row r, x index i) at
// (r * 5 + v) * mx + i; fluxes of direction d at d * fsize + (same index of the left cell).

// u32 parameters (uniform, 16-byte rows)
struct U { w: array<vec4<u32>, 8> }
@group(0) @binding(0) var<uniform> pu: U;
// real parameters
@group(0) @binding(1) var<storage, read> pr: array<real>;
@group(0) @binding(2) var<storage, read_write> cons: array<real>;
@group(0) @binding(3) var<storage, read_write> cons0: array<real>;
@group(0) @binding(4) var<storage, read_write> prim: array<real>;
@group(0) @binding(5) var<storage, read_write> flux: array<real>;
// red[0..16]: control reals; red[16..]: per-workgroup partial maxima of the wave rate
@group(0) @binding(6) var<storage, read_write> red: array<real>;
@group(0) @binding(7) var<storage, read_write> st: array<atomic<u32>>;
struct Stage { a: real, b: real, w: real, s: u32 }
@group(0) @binding(8) var<uniform> stg: Stage;

const NV: u32 = 5u;
const WG: u32 = 64u;
const RWG: u32 = 256u;

// u32 parameter slots
fn n(d: u32) -> u32 { return pu.w[0][d]; }
fn g(d: u32) -> u32 { return pu.w[1][d]; }
fn m(d: u32) -> u32 { return pu.w[2][d]; }
fn nd() -> u32 { return ND; }
fn limiter() -> u32 { return LIMITER; }
fn fsize() -> u32 { return pu.w[2][3]; }
fn nparts() -> u32 { return pu.w[3][0]; }
// workgroups per component of the boundary impulse sum (partials after the wave-rate ones)
fn iparts() -> u32 { return pu.w[3][1]; }
// boundary code of direction d, side s: 0 wall/symmetry, 1 outflow, 2 periodic, 3 inflow
fn bc(d: u32, s: u32) -> u32 { return pu.w[4 + d][s]; }

// real parameter slots
fn gamma() -> real { return pr[0]; }
fn inv_g() -> real { return pr[1]; }
fn off() -> real { return pr[2]; }
fn cfl() -> real { return pr[3]; }
fn inf() -> real { return pr[4]; }
fn maxr() -> real { return pr[5]; }
fn snap() -> real { return pr[6]; }
fn minpos() -> real { return pr[7]; }
fn idx(d: u32) -> real { return pr[8u + d]; }
fn area(d: u32) -> real { return pr[11u + d]; }
fn inflow(d: u32, s: u32, v: u32) -> real { return pr[14u + (d * 2u + s) * NV + v]; }
fn cell_volume() -> real { return pr[44]; }
// p∞ of a stiffened gas (0 for an ideal gas): ρc² = γ (p + p∞), the CPU's rho_c2
fn p_inf() -> real { return pr[48]; }

// control slots: red[0] time, red[1] t_end (or dt cap), red[2] dt, red[3] rate,
// red[4..7] boundary impulse, red[7] boundary work; st[0] active, st[1] steps, st[2] substeps, st[3] error,
// st[4] first bad cell, st[5] stage of the error, st[6] mode, st[7] step target
// (every error sets st[3] and clears st[0] together: one word says both)
fn running() -> bool {
    return atomicLoad(&st[0]) == 1u;
}

fn lin(gid: vec3<u32>, nwg: vec3<u32>, wg: u32) -> u32 {
    return gid.x + gid.y * nwg.x * wg;
}

fn mx() -> u32 { return m(0u); }
fn row(j: u32, k: u32) -> u32 { return j + k * m(1u); }
fn at(r: u32, v: u32, i: u32) -> u32 { return (r * NV + v) * mx() + i; }
fn finite(x: real) -> bool { return x <= maxr() && x >= -maxr(); }

// ---------------------------------------------------------------- primitives + wave rate

// step.rs prim_row_fast for cell id (interior enumeration); returns the cell's wave rate
// Σ_d (|u_d| + c)/Δx_d (max_rate), or 0 outside the interior.
fn prim_cell(id: u32) -> real {
    let total = n(0u) * n(1u) * n(2u);
    if id >= total {
        return real(0.0);
    }
    let i = g(0u) + id % n(0u);
    let q = id / n(0u);
    let j = g(1u) + q % n(1u);
    let k = g(2u) + q / n(1u);
    let b = at(row(j, k), 0u, i);
    let w = mx();
    let a = cons[b];
    let rho = real(0.0) + a;
    let inv = real(1.0) / rho;
    let u = cons[b + w] * inv;
    let v = cons[b + 2u * w] * inv;
    let ww = cons[b + 3u * w] * inv;
    let rhoe = cons[b + 4u * w] - real(0.5) * rho * (u * u + v * v + ww * ww);
    let p = (rhoe - real(1.0) * off()) / inv_g();
    let cc = gamma() * (p + p_inf()) / rho;
    let ok = a >= real(0.0) && rho > real(0.0) && cc > real(0.0) && finite(cc) && finite(p);
    if !ok && running() {
        atomicMin(&st[4], b);
        atomicStore(&st[5], stg.s);
        atomicStore(&st[3], 1u);
        atomicStore(&st[0], 0u);
    }
    prim[b] = a;
    prim[b + w] = u;
    prim[b + 2u * w] = v;
    prim[b + 3u * w] = ww;
    prim[b + 4u * w] = p;
    // max_rate: the same arithmetic on the stored primitives
    let c2 = gamma() * (p + p_inf()) / a;
    var c = inf();
    if a > real(0.0) && c2 > real(0.0) && finite(c2) {
        c = sqrt(c2);
    }
    var s = real(0.0);
    var vel = array<real, 3>(u, v, ww);
    for (var d = 0u; d < nd(); d++) {
        s += (abs(vel[d]) + c) * idx(d);
    }
    return s;
}

var<workgroup> sh: array<real, RWG>;

@compute @workgroup_size(RWG)
fn prim_rate(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) nwg: vec3<u32>,
             @builtin(local_invocation_index) li: u32,
             @builtin(workgroup_id) wid: vec3<u32>) {
    var s = real(0.0);
    if running() {
        s = prim_cell(lin(gid, nwg, RWG));
    }
    sh[li] = s;
    workgroupBarrier();
    for (var h = RWG / 2u; h > 0u; h = h / 2u) {
        if li < h {
            sh[li] = max(sh[li], sh[li + h]);
        }
        workgroupBarrier();
    }
    if li == 0u {
        red[16u + wid.x + wid.y * nwg.x] = sh[0];
    }
}

@compute @workgroup_size(RWG)
fn prim_only(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) nwg: vec3<u32>) {
    let id = lin(gid, nwg, RWG);
    if id < n(0u) * n(1u) * n(2u) && running() {
        _ = prim_cell(id);
    }
}

// The largest wave rate (order-independent: max is exact) and the step
// dt = min(cfl / rate, t_end - time) (mode 0) or min(cfl / rate, cap) (mode 1).
@compute @workgroup_size(RWG)
fn reduce_dt(@builtin(local_invocation_index) li: u32) {
    var mm = real(0.0);
    for (var t = li; t < nparts(); t += RWG) {
        mm = max(mm, red[16u + t]);
    }
    sh[li] = mm;
    workgroupBarrier();
    for (var h = RWG / 2u; h > 0u; h = h / 2u) {
        if li < h {
            sh[li] = max(sh[li], sh[li + h]);
        }
        workgroupBarrier();
    }
    if li == 0u && running() {
        let rate = sh[0];
        red[3] = rate;
        if !(rate > real(0.0)) || !finite(rate) {
            atomicStore(&st[3], 2u);
            atomicStore(&st[0], 0u);
            return;
        }
        var cap = red[1] - red[0];
        if atomicLoad(&st[6]) == 1u {
            cap = red[1];
        }
        red[2] = min(cfl() / rate, cap);
    }
}

// ---------------------------------------------------------------- ghost cells (boundary.rs)

// (ghost, mirror, inner, wrap) indices along a direction with g ghosts and n interior cells
fn ghost_src(side: u32, l: u32, gd: u32, nn: u32, code: u32) -> vec2<u32> {
    var gi: u32;
    var mirror: u32;
    var inner: u32;
    var wrap: u32;
    if side == 0u {
        gi = gd - 1u - l; mirror = gd + l; inner = gd; wrap = gd + nn - 1u - l;
    } else {
        gi = gd + nn + l; mirror = gd + nn - 1u - l; inner = gd + nn - 1u; wrap = gd + l;
    }
    var src = mirror;
    if code == 1u { src = inner; }
    if code == 2u { src = wrap; }
    return vec2<u32>(gi, src);
}

@compute @workgroup_size(WG)
fn ghost_x(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let id = lin(gid, nwg, WG);
    let gx = g(0u);
    if id >= n(1u) * n(2u) * 2u * gx * NV || !running() {
        return;
    }
    let v = id % NV;
    var q = id / NV;
    let l = q % gx;
    q = q / gx;
    let side = q % 2u;
    let rr = q / 2u;
    let r = row(g(1u) + rr % n(1u), g(2u) + rr / n(1u));
    let code = bc(0u, side);
    let gs = ghost_src(side, l, gx, n(0u), code);
    var val: real;
    if code == 3u {
        val = inflow(0u, side, v);
    } else {
        val = prim[at(r, v, gs.y)];
        if code == 0u && v == 1u {
            val = -val;
        }
    }
    prim[at(r, v, gs.x)] = val;
}

// whole rows along d = 1 (lines over interior k) or d = 2 (lines over every j)
fn ghost_rows(id: u32, d: u32) {
    let gd = g(d);
    var nlines = n(2u);
    if d == 2u { nlines = m(1u); }
    if id >= nlines * 2u * gd * NV * mx() || !running() {
        return;
    }
    let i = id % mx();
    var q = id / mx();
    let v = q % NV;
    q = q / NV;
    let l = q % gd;
    q = q / gd;
    let side = q % 2u;
    let line = q / 2u;
    var r0: u32;
    var stride: u32;
    if d == 1u {
        r0 = row(g(1u), g(2u) + line);
        stride = 1u;
    } else {
        r0 = row(line, g(2u));
        stride = m(1u);
    }
    let code = bc(d, side);
    let gs = ghost_src(side, l, gd, n(d), code);
    let dst = r0 + gs.x * stride - gd * stride;
    var val: real;
    if code == 3u {
        val = inflow(d, side, v);
    } else {
        let src = r0 + gs.y * stride - gd * stride;
        val = prim[at(src, v, i)];
        if code == 0u && v == 1u + d {
            val = -val;
        }
    }
    prim[at(dst, v, i)] = val;
}

@compute @workgroup_size(WG)
fn ghost_y(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    ghost_rows(lin(gid, nwg, WG), 1u);
}

@compute @workgroup_size(WG)
fn ghost_z(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    ghost_rows(lin(gid, nwg, WG), 2u);
}

// ---------------------------------------------------------------- MUSCL + HLLC

fn slope(a: real, b: real) -> real {
    let lim = limiter();
    if lim == 0u {
        // minmod
        if a * b <= real(0.0) {
            return real(0.0);
        } else if abs(a) < abs(b) {
            return a;
        }
        return b;
    } else if lim == 1u {
        // van Leer
        let ab = a * b;
        if ab <= real(0.0) {
            return real(0.0);
        }
        return real(2.0) * ab / (a + b);
    }
    // monotonised central
    if a * b <= real(0.0) {
        return real(0.0);
    }
    let c = real(0.5) * (a + b);
    let mm = min(min(real(2.0) * abs(a), real(2.0) * abs(b)), abs(c));
    if a < real(0.0) {
        return -mm;
    }
    return mm;
}

struct Face { rho: real, vel: array<real, 3>, p: real, e: real, c: real, ok: bool }

// step.rs face_state for one material: c = sqrt(γ(p + p∞)/ρ), E = (p/Γ + off) + ½ρ|u|²
fn face(q: array<real, 5>) -> Face {
    var f: Face;
    let r = q[0];
    let p = q[4];
    f.rho = r;
    f.vel = array<real, 3>(q[1], q[2], q[3]);
    f.p = p;
    let c2 = gamma() * (p + p_inf()) / r;
    f.ok = r > real(0.0) && c2 > real(0.0) && finite(c2);
    f.c = real(0.0);
    if f.ok {
        f.c = sqrt(c2);
    }
    f.e = (p * inv_g() + real(1.0) * off()) + real(0.5) * r * (q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    return f;
}

// hllc.rs side(): F_K, plus s_K (U*_K - U_K) when the fan crosses the face
fn side(q: Face, sk: real, ss: real, d: u32) -> array<real, 5> {
    var f: array<real, 5>;
    var vel = q.vel;
    let un = vel[d];
    f[0] = q.rho * un;
    for (var c = 0u; c < 3u; c++) {
        f[1u + c] = q.rho * vel[c] * un;
    }
    f[1u + d] += q.p;
    f[4] = (q.e + q.p) * un;
    var crosses: bool;
    if sk < real(0.0) {
        crosses = real(0.0) <= ss && sk < real(0.0);
    } else {
        crosses = ss < real(0.0) && sk > real(0.0);
    }
    if crosses {
        let chi = (sk - un) / (sk - ss);
        let sc = sk * (chi - real(1.0));
        f[0] += sc * q.rho;
        for (var c = 0u; c < 3u; c++) {
            f[1u + c] += sc * q.rho * vel[c];
        }
        f[1u + d] += sk * chi * q.rho * (ss - un);
        let estar = chi * (q.e + (ss - un) * (q.rho * ss + q.p / (sk - un)));
        f[4] += sk * (estar - q.e);
    }
    return f;
}

// hllc.rs flux_dir(): Davis wave speeds, Toro's star speed
fn hllc(l: Face, r: Face, d: u32) -> array<real, 5> {
    var lv = l.vel;
    var rv = r.vel;
    let ul = lv[d];
    let ur = rv[d];
    let sl = min(ul - l.c, ur - r.c);
    let sr = max(ul + l.c, ur + r.c);
    let ml = l.rho * (sl - ul);
    let mr = r.rho * (sr - ur);
    let num = (r.p - l.p) + (ml * ul - mr * ur);
    let den = ml - mr;
    let ss = num / den;
    if ss >= real(0.0) {
        return side(l, sl, ss, d);
    }
    return side(r, sr, ss, d);
}

// one face normal to d: stencil cells (left-1, left, right, right+1); stored at the left cell
fn flux_face(id: u32, d: u32) {
    var cnt = vec3<u32>(n(0u), n(1u), n(2u));
    cnt[d] += 1u;
    if id >= cnt.x * cnt.y * cnt.z || !running() {
        return;
    }
    var e = vec3<u32>(0u, 0u, 0u);
    e[d] = 1u;
    let a = id % cnt.x;
    let qq = id / cnt.x;
    let i = g(0u) + a - e.x;
    let j = g(1u) + qq % cnt.y - e.y;
    let k = g(2u) + qq / cnt.y - e.z;
    let base = at(row(j, k), 0u, i);
    var s = 1u;
    if d == 1u { s = NV * mx(); }
    if d == 2u { s = NV * mx() * m(1u); }
    var lq: array<real, 5>;
    var rq: array<real, 5>;
    for (var v = 0u; v < NV; v++) {
        let o = base + v * mx();
        let a0 = prim[o - s];
        let a1 = prim[o];
        let a2 = prim[o + s];
        let a3 = prim[o + 2u * s];
        let dm = a1 - a0;
        let dc = a2 - a1;
        let dp = a3 - a2;
        lq[v] = a1 + real(0.5) * slope(dm, dc);
        rq[v] = a2 - real(0.5) * slope(dc, dp);
    }
    var fl = face(lq);
    var fr = face(rq);
    var f: array<real, 5>;
    if fl.ok && fr.ok {
        f = hllc(fl, fr, d);
    } else {
        // first order where the reconstruction leaves the admissible set (rare: the cell
        // states are read again rather than kept live through the common path)
        var q1: array<real, 5>;
        var q2: array<real, 5>;
        for (var v = 0u; v < NV; v++) {
            q1[v] = prim[base + v * mx()];
            q2[v] = prim[base + v * mx() + s];
        }
        fl = face(q1);
        fr = face(q2);
        if fl.ok && fr.ok && q1[0] >= real(0.0) && q2[0] >= real(0.0) {
            f = hllc(fl, fr, d);
        } else {
            let nan = inf() - inf();
            f = array<real, 5>(nan, nan, nan, nan, nan);
        }
    }
    let fo = d * fsize() + base;
    for (var v = 0u; v < NV; v++) {
        flux[fo + v * mx()] = f[v];
    }
}

@compute @workgroup_size(WG)
fn flux_x(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    flux_face(lin(gid, nwg, WG), 0u);
}

@compute @workgroup_size(WG)
fn flux_y(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    flux_face(lin(gid, nwg, WG), 1u);
}

@compute @workgroup_size(WG)
fn flux_z(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    flux_face(lin(gid, nwg, WG), 2u);
}

// ---------------------------------------------------------------- RK stage update

// step.rs update(): U = a U0 + b (U + dt L(U)); stage 0 first saves U0 = U
@compute @workgroup_size(WG)
fn update(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let id = lin(gid, nwg, WG);
    if id >= n(0u) * n(1u) * n(2u) || !running() {
        return;
    }
    let i = g(0u) + id % n(0u);
    let q = id / n(0u);
    let j = g(1u) + q % n(1u);
    let k = g(2u) + q / n(1u);
    let base = at(row(j, k), 0u, i);
    let dt = red[2];
    let sy = NV * mx();
    let sz = NV * mx() * m(1u);
    let f1 = fsize();
    let f2 = 2u * fsize();
    for (var v = 0u; v < NV; v++) {
        let o = base + v * mx();
        let dfx = flux[o] - flux[o - 1u];
        var res = -dfx * idx(0u);
        if nd() > 1u {
            let dfy = flux[f1 + o] - flux[f1 + o - sy];
            res -= dfy * idx(1u);
        }
        if nd() > 2u {
            let dfz = flux[f2 + o] - flux[f2 + o - sz];
            res -= dfz * idx(2u);
        }
        let u = cons[o];
        if stg.s == 0u {
            cons0[o] = u;
        }
        let u0 = cons0[o];
        cons[o] = stg.a * u0 + stg.b * (u + dt * res);
    }
}

// ---------------------------------------------------------------- boundary impulse, clock

// Boundary face pair f of the domain (faces normal to x first, then y, then z; along each
// side x fastest, as the cells): the flux of momentum component c (0..3) or of the total energy
// (c = 3, the variable after the momentum) through the low-side face minus that through the
// high-side face opposite it, times the face area. A face whose domain cell is solid bounds no
// gas and counts zero. Pairing the two sides keeps a periodic direction's impulse exactly
// zero, as on the CPU (its two faces carry the same flux).
fn boundary_term(f: u32, c: u32) -> real {
    let v = 1u + c;
    var t = f;
    for (var d = 0u; d < nd(); d++) {
        var cnt: u32;
        if d == 0u {
            cnt = n(1u) * n(2u);
        } else if d == 1u {
            cnt = n(0u) * n(2u);
        } else {
            cnt = n(0u) * n(1u);
        }
        if t >= cnt {
            t -= cnt;
            continue;
        }
        let fo = d * fsize();
        // (face row, face x index, domain cell row, domain cell x index) of each side
        var lo = vec4<u32>();
        var hi = vec4<u32>();
        if d == 0u {
            let r = row(g(1u) + t % n(1u), g(2u) + t / n(1u));
            lo = vec4<u32>(r, g(0u) - 1u, r, g(0u));
            let ih = g(0u) + n(0u) - 1u;
            hi = vec4<u32>(r, ih, r, ih);
        } else {
            let i = g(0u) + t % n(0u);
            let o = t / n(0u);
            if d == 1u {
                lo = vec4<u32>(row(g(1u) - 1u, g(2u) + o), i, row(g(1u), g(2u) + o), i);
                let rh = row(g(1u) + n(1u) - 1u, g(2u) + o);
                hi = vec4<u32>(rh, i, rh, i);
            } else {
                lo = vec4<u32>(row(g(1u) + o, g(2u) - 1u), i, row(g(1u) + o, g(2u)), i);
                let rh = row(g(1u) + o, g(2u) + n(2u) - 1u);
                hi = vec4<u32>(rh, i, rh, i);
            }
        }
        var x = real(0.0);
        var y = real(0.0);
        if !is_solid_cell(lo.z * mx() + lo.w) {
            x = flux[fo + at(lo.x, v, lo.y)];
        }
        if !is_solid_cell(hi.z * mx() + hi.w) {
            y = flux[fo + at(hi.x, v, hi.y)];
        }
        return area(d) * (x - y);
    }
    return real(0.0);
}

fn boundary_pairs() -> u32 {
    var total = 0u;
    for (var d = 0u; d < nd(); d++) {
        if d == 0u {
            total += n(1u) * n(2u);
        } else if d == 1u {
            total += n(0u) * n(2u);
        } else {
            total += n(0u) * n(1u);
        }
    }
    return total;
}

// step.rs boundary_flux(), first level: workgroup (c, p) sums the boundary terms of
// component c (momentum x, y, z, energy) over every iparts()-th block of RWG face pairs,
// by a tree, into partial red[16 + nparts + c · iparts + p]
@compute @workgroup_size(RWG)
fn impulse(@builtin(local_invocation_index) li: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let c = wid.x;
    let p = wid.y;
    let total = boundary_pairs();
    var s = real(0.0);
    if running() {
        for (var f = p * RWG + li; f < total; f += iparts() * RWG) {
            s += boundary_term(f, c);
        }
    }
    sh[li] = s;
    workgroupBarrier();
    for (var h = RWG / 2u; h > 0u; h = h / 2u) {
        if li < h {
            sh[li] = sh[li] + sh[li + h];
        }
        workgroupBarrier();
    }
    if li == 0u {
        red[16u + nparts() + c * iparts() + p] = sh[0];
    }
}

// second level: thread c adds the stage's impulse, the partials summed in order (the order
// differs from the CPU's: agreement to round-off, not bit for bit; a periodic direction
// stays exactly zero)
@compute @workgroup_size(4)
fn impulse_sum(@builtin(local_invocation_index) c: u32) {
    if c >= 4u || !running() {
        return;
    }
    var s = real(0.0);
    for (var p = 0u; p < iparts(); p++) {
        s += red[16u + nparts() + c * iparts() + p];
    }
    red[4u + c] += stg.w * red[2] * s;
}

// advance_to(): time += dt, snapped onto t_end within 1e-12 relative; stop at t_end
@compute @workgroup_size(1)
fn finish() {
    if !running() {
        return;
    }
    var time = red[0] + red[2];
    let t1 = red[1];
    let mode = atomicLoad(&st[6]);
    if mode == 0u && t1 - time <= snap() * max(abs(t1), minpos()) {
        time = t1;
    }
    red[0] = time;
    atomicAdd(&st[1], 1u);
    let sub = atomicAdd(&st[2], 1u) + 1u;
    if (mode == 0u && !(time < t1)) || (mode == 1u && sub >= atomicLoad(&st[7])) {
        atomicStore(&st[0], 0u);
    }
}

// ---------------------------------------------------------------- diagnostics

// diagnostics.rs totals(), one interior row per thread in x order: mass, momentum,
// kinetic and internal energy, largest pressure, momentum scale, least pressure and density,
// solid cells of an immersed body skipped (is_solid_cell: immersed.wgsl, or `false` without an
// interface); written to the flux buffer (scratch between steps) at 10 t + q for the t-th
// interior row. The host sums rows in order.
@compute @workgroup_size(WG)
fn row_totals(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = lin(gid, nwg, WG);
    if t >= n(1u) * n(2u) {
        return;
    }
    let r = row(g(1u) + t % n(1u), g(2u) + t / n(1u));
    let vol = cell_volume();
    var mass = real(0.0);
    var mom = array<real, 3>(real(0.0), real(0.0), real(0.0));
    var kin = real(0.0);
    var int = real(0.0);
    var pmax = real(0.0);
    var gross = real(0.0);
    var pmin = real(1.0e30);
    var rmin = real(1.0e30);
    for (var i = g(0u); i < g(0u) + n(0u); i++) {
        if is_solid_cell(r * mx() + i) {
            continue;
        }
        let ar = max(cons[at(r, 0u, i)], real(0.0));
        let rho = real(0.0) + ar;
        let m0 = cons[at(r, 1u, i)];
        let m1 = cons[at(r, 2u, i)];
        let m2 = cons[at(r, 3u, i)];
        let e = cons[at(r, 4u, i)];
        let v0 = m0 / rho;
        let v1 = m1 / rho;
        let v2 = m2 / rho;
        let rhoe = e - real(0.5) * rho * (v0 * v0 + v1 * v1 + v2 * v2);
        let p = (rhoe - real(1.0) * off()) / inv_g();
        let ke = real(0.5) * rho * (v0 * v0 + v1 * v1 + v2 * v2);
        mass += rho * vol;
        mom[0] += m0 * vol;
        mom[1] += m1 * vol;
        mom[2] += m2 * vol;
        kin += ke * vol;
        int += (e - ke) * vol;
        pmax = max(pmax, p);
        pmin = min(pmin, p);
        rmin = min(rmin, rho);
        gross += sqrt(m0 * m0 + m1 * m1 + m2 * m2) * vol;
    }
    let o = 10u * t;
    flux[o] = mass;
    flux[o + 1u] = mom[0];
    flux[o + 2u] = mom[1];
    flux[o + 3u] = mom[2];
    flux[o + 4u] = kin;
    flux[o + 5u] = int;
    flux[o + 6u] = pmax;
    flux[o + 7u] = gross;
    flux[o + 8u] = pmin;
    flux[o + 9u] = rmin;
}
