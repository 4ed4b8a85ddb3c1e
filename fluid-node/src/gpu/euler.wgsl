// The five-equation multi-material Euler step on the device (seed 002 §2.2–§2.4, Fig. 4; one
// to four materials, each an ideal gas, a stiffened gas or JWL products): primitive recovery
// with the mixture closure in mechanical equilibrium, ghost fill, MUSCL + HLLC fluxes with the
// Johnsen–Colonius face velocity for the volume fractions, SSP-RK3 stage update (seed 002
// eq. 35 weights), boundary impulse, and the CFL reduction. Every formula mirrors fluid-node's
// CPU kernels (step.rs, mixture.rs, eos/, riemann/, limiter.rs, boundary.rs) operation by
// operation, so the f64 results agree with the CPU to round-off.
//
// `real` is f64 or f32: the host prepends `alias real = f64;` (or f32), the model's limiter,
// dimension and materials as constants (`LIMITER`, `ND`, `NM` materials, `NV` = 2 NM + 3
// variables, `NF` flux entries per face: NV, and one more, the face velocity, with several
// materials; `JWL`, a bit per JWL material) and `rexp`, the exponential of the JWL reference
// curve, so the driver compiles one limiter, only the directions the grid has and only the
// equations of state the model uses.
// Layout: the CPU's row-blocked structure of arrays, value v of cell (row r, x index i) at
// (r * NV + v) * mx + i; fluxes of direction d at d * fsize + (r * NF + v) * mx + i, indexed by
// the cell left of the face.

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
// boundary code of direction d, side s: 0 wall/symmetry, 1 outflow, 2 periodic, 3 inflow,
// 4 non-reflecting
fn bc(d: u32, s: u32) -> u32 { return pu.w[4 + d][s]; }

// real parameter slots
fn cfl() -> real { return pr[3]; }
fn inf() -> real { return pr[4]; }
fn maxr() -> real { return pr[5]; }
fn snap() -> real { return pr[6]; }
fn minpos() -> real { return pr[7]; }
fn idx(d: u32) -> real { return pr[8u + d]; }
fn area(d: u32) -> real { return pr[11u + d]; }
fn cell_volume() -> real { return pr[44]; }
// a non-reflecting face's far field (FarField in boundary.rs): impedance, relaxation per fill,
// pressure and velocity along the face's axis, four reals per face from slot 14
fn far(d: u32, s: u32, k: u32) -> real { return pr[14u + (d * 2u + s) * 4u + k]; }
// material k's constants (MAT reals each): 1/Γ, the offset -p_ref/Γ of a constant-reference
// phase, Γ, γ and p∞ (ρc² = γ (p + p∞) of an ideal or stiffened gas, eos/), and JWL's ρ0,
// A, B, R1, R2, ω
const MAT0: u32 = 50u;
const MAT: u32 = 12u;
fn mp(k: u32, s: u32) -> real { return pr[MAT0 + MAT * k + s]; }
fn inv_g(k: u32) -> real { return mp(k, 0u); }
fn off(k: u32) -> real { return mp(k, 1u); }
// the inflow state of direction d, side s (NV primitives), after the materials
fn inflow(d: u32, s: u32, v: u32) -> real { return pr[MAT0 + MAT * 4u + (d * 2u + s) * NV + v]; }

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
// flux entry v of the face right of cell (row r, x index i)
fn fat(r: u32, v: u32, i: u32) -> u32 { return (r * NF + v) * mx() + i; }

// ---------------------------------------------------------------- equations of state (eos/)

fn is_jwl(k: u32) -> bool { return ((JWL >> k) & 1u) == 1u; }

// jwl.rs p_ref and dp_ref at ρ (V = ρ0/ρ), the two exponentials computed once:
// p_ref = A (1 - ω/(R1 V)) e^{-R1 V} + B (1 - ω/(R2 V)) e^{-R2 V},
// dp_ref = -(dp_ref/dV) V/ρ with dp_ref/dV = A e^{-R1 V} (ω/(R1 V²) - R1 + ω/V) + (B, R2)
fn jwl_ref(k: u32, rho: real) -> vec2<real> {
    let v = mp(k, 5u) / rho;
    let w = mp(k, 10u);
    let r1 = mp(k, 8u);
    let r2 = mp(k, 9u);
    let e1 = rexp(-r1 * v);
    let e2 = rexp(-r2 * v);
    let a = mp(k, 6u);
    let b = mp(k, 7u);
    let p = a * (real(1.0) - w / (r1 * v)) * e1 + b * (real(1.0) - w / (r2 * v)) * e2;
    let t1 = a * e1 * (w / (r1 * v * v) - r1 + w / v);
    let t2 = b * e2 * (w / (r2 * v * v) - r2 + w / v);
    return vec2<real>(p, -(t1 + t2) * v / rho);
}

fn jwl_p_ref(k: u32, rho: real) -> real {
    let v = mp(k, 5u) / rho;
    let w = mp(k, 10u);
    let r1 = mp(k, 8u);
    let r2 = mp(k, 9u);
    return mp(k, 6u) * (real(1.0) - w / (r1 * v)) * rexp(-r1 * v)
        + mp(k, 7u) * (real(1.0) - w / (r2 * v)) * rexp(-r2 * v);
}

// Eos::rho_c2 of material k at (ρ, p)
fn rho_c2(k: u32, rho: real, p: real) -> real {
    if is_jwl(k) {
        let g = mp(k, 2u);
        let rf = jwl_ref(k, rho);
        return rho * (rf.y - g * rho * real(0.0)) + (g + real(1.0)) * p - rf.x;
    }
    return mp(k, 3u) * (p + mp(k, 4u));
}

// ---------------------------------------------------------------- mixture (mixture.rs)

// Phase::offset: α (ρ_k e_ref - p_ref/Γ), ρ_k = ar/α
fn phase_offset(k: u32, ar: real, al: real) -> real {
    if !is_jwl(k) {
        return al * off(k);
    }
    if al > real(1e-8) {
        let rk = ar / al;
        return al * (rk * real(0.0) - jwl_p_ref(k, rk) * inv_g(k));
    }
    return real(0.0);
}

// Phase::axrc2: α ξ_k ρ_k c_k²
fn phase_axrc2(k: u32, ar: real, al: real, p: real) -> real {
    if !is_jwl(k) {
        return al * inv_g(k) * rho_c2(k, real(1.0), p);
    }
    if al > real(1e-8) {
        return al * inv_g(k) * rho_c2(k, ar / al, p);
    }
    return real(0.0);
}

// mixture::pressure from partial densities, volume fractions and ρe
fn mix_pressure(ar: array<real, NM>, al: array<real, NM>, rhoe: real) -> real {
    if NM == 1u {
        return (rhoe - phase_offset(0u, ar[0], real(1.0))) / inv_g(0u);
    }
    var xi = real(0.0);
    var o = real(0.0);
    for (var k = 0u; k < NM; k++) {
        xi += al[k] * inv_g(k);
        o += phase_offset(k, ar[k], al[k]);
    }
    return (rhoe - o) / xi;
}

// mixture::rhoe at pressure p
fn mix_rhoe(ar: array<real, NM>, al: array<real, NM>, p: real) -> real {
    if NM == 1u {
        return p * inv_g(0u) + phase_offset(0u, ar[0], real(1.0));
    }
    var xi = real(0.0);
    var o = real(0.0);
    for (var k = 0u; k < NM; k++) {
        xi += al[k] * inv_g(k);
        o += phase_offset(k, ar[k], al[k]);
    }
    return p * xi + o;
}

// mixture::sound_speed2 (frozen); non-positive or NaN marks an inadmissible state
fn mix_c2(ar: array<real, NM>, al: array<real, NM>, rho: real, p: real) -> real {
    if NM == 1u {
        return rho_c2(0u, rho, p) / rho;
    }
    var xi = real(0.0);
    var s = real(0.0);
    for (var k = 0u; k < NM; k++) {
        xi += al[k] * inv_g(k);
        s += phase_axrc2(k, ar[k], al[k], p);
    }
    return s / (rho * xi);
}

// ---------------------------------------------------------------- primitives + wave rate

// step.rs prim_row for cell id (interior enumeration); returns the cell's wave rate
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
    var ar: array<real, NM>;
    var al: array<real, NM>;
    var rho = real(0.0);
    var ok = true;
    // tiny negative partial densities of a trace phase are round-off (several materials)
    var sabs = real(0.0);
    if NM > 1u {
        for (var m = 0u; m < NM; m++) {
            sabs += abs(cons[b + m * w]);
        }
    }
    for (var m = 0u; m < NM; m++) {
        let a = cons[b + m * w];
        if !(a >= real(0.0)) {
            if NM > 1u && a > real(-1e-12) * sabs {
                ar[m] = real(0.0);
                continue;
            }
            ok = false;
        }
        ar[m] = a;
        rho += a;
    }
    let inv = real(1.0) / rho;
    let u = cons[b + NM * w] * inv;
    let v = cons[b + (NM + 1u) * w] * inv;
    let ww = cons[b + (NM + 2u) * w] * inv;
    let rhoe = cons[b + (NM + 3u) * w] - real(0.5) * rho * (u * u + v * v + ww * ww);
    var sa = real(0.0);
    for (var m = 0u; m + 1u < NM; m++) {
        let a = cons[b + (NM + 4u + m) * w];
        al[m] = a;
        sa += a;
    }
    al[NM - 1u] = max(real(1.0) - sa, real(0.0));
    let p = mix_pressure(ar, al, rhoe);
    let cc = mix_c2(ar, al, rho, p);
    ok = ok && rho > real(0.0) && cc > real(0.0) && finite(cc) && finite(p);
    if !ok && running() {
        atomicMin(&st[4], b);
        atomicStore(&st[5], stg.s);
        atomicStore(&st[3], 1u);
        atomicStore(&st[0], 0u);
    }
    for (var m = 0u; m < NM; m++) {
        prim[b + m * w] = ar[m];
    }
    prim[b + NM * w] = u;
    prim[b + (NM + 1u) * w] = v;
    prim[b + (NM + 2u) * w] = ww;
    prim[b + (NM + 3u) * w] = p;
    // max_rate: the sound speed `face` gives the stored primitives, c = ∞ where it rejects
    // them. Their partial densities are ≥ 0 and sum to ρ, and the last volume fraction
    // `face` forms from theirs is the one above (1 - Σ, or 0 within 1e-12 of 1) unless it
    // is negative, which it rejects: so c² is `cc`.
    var fok = rho > real(0.0) && cc > real(0.0) && finite(cc);
    for (var m = 0u; m + 1u < NM; m++) {
        prim[b + (NM + 4u + m) * w] = al[m];
        fok = fok && al[m] >= real(0.0) && al[m] <= real(1.0);
    }
    if NM > 1u {
        var last = real(1.0) - sa;
        if sa > real(1.0) && sa < real(1.0) + real(1e-12) {
            last = real(0.0);
        }
        fok = fok && !(last < real(0.0));
    }
    var c = inf();
    if fok {
        c = sqrt(cc);
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
    if code == 1u || code == 4u { src = inner; }
    if code == 2u { src = wrap; }
    return vec2<u32>(gi, src);
}

// A non-reflecting face's ghost pressure (or, `want_u`, its velocity along the face's axis)
// from the interior cell's pressure `p` and velocity `u` along it: FarField::ghost, operation
// by operation.
fn far_ghost(d: u32, side: u32, want_u: bool, p: real, u: real) -> real {
    let z = far(d, side, 0u);
    var sign = real(1.0);
    if side == 0u { sign = real(-1.0); }
    let out = p + z * sign * u;
    var inc = p - z * sign * u;
    inc = inc + far(d, side, 1u) * ((far(d, side, 2u) - z * sign * far(d, side, 3u)) - inc);
    if want_u {
        return sign * (out - inc) / (real(2.0) * z);
    }
    return real(0.5) * (out + inc);
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
        if code == 0u && v == NM {
            val = -val;
        }
        if code == 4u && (v == NM || v == NM + 3u) {
            val = far_ghost(0u, side, v == NM, prim[at(r, NM + 3u, gs.y)], prim[at(r, NM, gs.y)]);
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
        if code == 0u && v == NM + d {
            val = -val;
        }
        if code == 4u && (v == NM + d || v == NM + 3u) {
            val = far_ghost(d, side, v == NM + d, prim[at(src, NM + 3u, i)], prim[at(src, NM + d, i)]);
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

struct Face {
    ar: array<real, NM>,
    al: array<real, NM>,
    rho: real,
    vel: array<real, 3>,
    p: real,
    e: real,
    c: real,
    ok: bool,
}

// riemann/mod.rs face_state: partial densities ≥ 0, volume fractions in [0, 1] (the last one
// 1 - Σ, a hair below zero taken as zero), ρ > 0, c² > 0 and finite;
// E = ρe(p) + ½ρ|u|² (mixture.rs)
fn face(q: array<real, NV>) -> Face {
    var f: Face;
    if NM == 1u {
        // one material: ρ = q0, c = √(ρc²(ρ, p)/ρ), E = (p/Γ + off) + ½ρ|u|² (the
        // general form below with its sums of one term)
        let r = q[0];
        let p = q[NM + 3u];
        f.ar[0] = r;
        f.al[0] = real(1.0);
        f.rho = r;
        f.vel = array<real, 3>(q[NM], q[NM + 1u], q[NM + 2u]);
        f.p = p;
        let c2 = rho_c2(0u, r, p) / r;
        f.ok = r > real(0.0) && c2 > real(0.0) && finite(c2);
        f.c = real(0.0);
        if f.ok {
            f.c = sqrt(c2);
        }
        f.e = (p * inv_g(0u) + phase_offset(0u, r, real(1.0))) + real(0.5) * r * (f.vel[0] * f.vel[0] + f.vel[1] * f.vel[1] + f.vel[2] * f.vel[2]);
        return f;
    }
    var ok = true;
    var rho = real(0.0);
    for (var k = 0u; k < NM; k++) {
        f.ar[k] = q[k];
        rho += q[k];
        if !(q[k] >= real(0.0)) {
            ok = false;
        }
    }
    var sa = real(0.0);
    for (var k = 0u; k + 1u < NM; k++) {
        let a = q[NM + 4u + k];
        if !(a >= real(0.0) && a <= real(1.0)) {
            ok = false;
        }
        f.al[k] = a;
        sa += a;
    }
    var last = real(1.0) - sa;
    if sa > real(1.0) && sa < real(1.0) + real(1e-12) {
        last = real(0.0);
    }
    f.al[NM - 1u] = last;
    if !(rho > real(0.0)) || last < real(0.0) {
        ok = false;
    }
    f.rho = rho;
    f.vel = array<real, 3>(q[NM], q[NM + 1u], q[NM + 2u]);
    let p = q[NM + 3u];
    f.p = p;
    let c2 = mix_c2(f.ar, f.al, rho, p);
    ok = ok && c2 > real(0.0) && finite(c2);
    f.ok = ok;
    f.c = real(0.0);
    if ok {
        f.c = sqrt(c2);
    }
    f.e = mix_rhoe(f.ar, f.al, p) + real(0.5) * rho * (f.vel[0] * f.vel[0] + f.vel[1] * f.vel[1] + f.vel[2] * f.vel[2]);
    return f;
}

// hllc.rs side(): F_K, plus s_K (U*_K - U_K) when the fan crosses the face; with several
// materials the α entries carry α u and the last entry the face velocity (Johnsen–Colonius)
fn side(q: Face, sk: real, ss: real, d: u32) -> array<real, NF> {
    var f: array<real, NF>;
    var vel = q.vel;
    let un = vel[d];
    for (var k = 0u; k < NM; k++) {
        f[k] = q.ar[k] * un;
    }
    for (var c = 0u; c < 3u; c++) {
        f[NM + c] = q.rho * vel[c] * un;
    }
    f[NM + d] += q.p;
    f[NM + 3u] = (q.e + q.p) * un;
    for (var k = 0u; k + 1u < NM; k++) {
        f[NM + 4u + k] = q.al[k] * un;
    }
    if NF > NV {
        f[NF - 1u] = un;
    }
    var crosses: bool;
    if sk < real(0.0) {
        crosses = real(0.0) <= ss && sk < real(0.0);
    } else {
        crosses = ss < real(0.0) && sk > real(0.0);
    }
    if crosses {
        let chi = (sk - un) / (sk - ss);
        let sc = sk * (chi - real(1.0));
        for (var k = 0u; k < NM; k++) {
            f[k] += sc * q.ar[k];
        }
        for (var c = 0u; c < 3u; c++) {
            f[NM + c] += sc * q.rho * vel[c];
        }
        f[NM + d] += sk * chi * q.rho * (ss - un);
        let estar = chi * (q.e + (ss - un) * (q.rho * ss + q.p / (sk - un)));
        f[NM + 3u] += sk * (estar - q.e);
        for (var k = 0u; k + 1u < NM; k++) {
            f[NM + 4u + k] += sc * q.al[k];
        }
        if NF > NV {
            f[NF - 1u] += sc;
        }
    }
    return f;
}

// hllc.rs flux_dir(): Davis wave speeds, Toro's star speed
fn hllc(l: Face, r: Face, d: u32) -> array<real, NF> {
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

fn nan_flux() -> array<real, NF> {
    let nan = inf() - inf();
    var f: array<real, NF>;
    for (var v = 0u; v < NF; v++) {
        f[v] = nan;
    }
    return f;
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
    let r0 = row(j, k);
    let base = at(r0, 0u, i);
    var s = 1u;
    if d == 1u { s = NV * mx(); }
    if d == 2u { s = NV * mx() * m(1u); }
    var lq: array<real, NV>;
    var rq: array<real, NV>;
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
    var f: array<real, NF>;
    if fl.ok && fr.ok {
        f = hllc(fl, fr, d);
    } else {
        // first order where the reconstruction leaves the admissible set (rare: the cell
        // states are read again rather than kept live through the common path)
        var q1: array<real, NV>;
        var q2: array<real, NV>;
        for (var v = 0u; v < NV; v++) {
            q1[v] = prim[base + v * mx()];
            q2[v] = prim[base + v * mx() + s];
        }
        fl = face(q1);
        fr = face(q2);
        if fl.ok && fr.ok {
            f = hllc(fl, fr, d);
        } else {
            f = nan_flux();
        }
    }
    let fo = d * fsize() + fat(r0, 0u, i);
    for (var v = 0u; v < NF; v++) {
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

// step.rs update(): U = a U0 + b (U + dt L(U)); stage 0 first saves U0 = U. A volume
// fraction adds the Johnsen–Colonius term α ∇·u_face (update_var) and is clamped to [0, 1].
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
    let r = row(j, k);
    let base = at(r, 0u, i);
    let fbase = fat(r, 0u, i);
    let dt = red[2];
    let sy = NF * mx();
    let sz = NF * mx() * m(1u);
    let f1 = fsize();
    let f2 = 2u * fsize();
    // the face velocities' entries (several materials)
    let uo = fbase + (NF - 1u) * mx();
    for (var v = 0u; v < NV; v++) {
        let o = base + v * mx();
        let fo = fbase + v * mx();
        let alpha = v >= NM + 4u;
        let u = cons[o];
        var dfx = flux[fo] - flux[fo - 1u];
        if alpha {
            dfx -= u * (flux[uo] - flux[uo - 1u]);
        }
        var res = -dfx * idx(0u);
        if nd() > 1u {
            var dfy = flux[f1 + fo] - flux[f1 + fo - sy];
            if alpha {
                dfy -= u * (flux[f1 + uo] - flux[f1 + uo - sy]);
            }
            res -= dfy * idx(1u);
        }
        if nd() > 2u {
            var dfz = flux[f2 + fo] - flux[f2 + fo - sz];
            if alpha {
                dfz -= u * (flux[f2 + uo] - flux[f2 + uo - sz]);
            }
            res -= dfz * idx(2u);
        }
        if stg.s == 0u {
            cons0[o] = u;
        }
        let u0 = cons0[o];
        var nu = stg.a * u0 + stg.b * (u + dt * res);
        if alpha {
            if nu < real(0.0) {
                nu = real(0.0);
            }
            if nu > real(1.0) {
                nu = real(1.0);
            }
        }
        cons[o] = nu;
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
    let v = NM + c;
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
            x = flux[fo + fat(lo.x, v, lo.y)];
        }
        if !is_solid_cell(hi.z * mx() + hi.w) {
            y = flux[fo + fat(hi.x, v, hi.y)];
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
        // diagnostics.rs cell_prim
        var ar: array<real, NM>;
        var al: array<real, NM>;
        var rho = real(0.0);
        for (var k = 0u; k < NM; k++) {
            ar[k] = max(cons[at(r, k, i)], real(0.0));
            rho += ar[k];
        }
        var sa = real(0.0);
        for (var k = 0u; k + 1u < NM; k++) {
            al[k] = cons[at(r, NM + 4u + k, i)];
            sa += al[k];
        }
        al[NM - 1u] = real(1.0) - sa;
        let m0 = cons[at(r, NM, i)];
        let m1 = cons[at(r, NM + 1u, i)];
        let m2 = cons[at(r, NM + 2u, i)];
        let e = cons[at(r, NM + 3u, i)];
        let v0 = m0 / rho;
        let v1 = m1 / rho;
        let v2 = m2 / rho;
        let rhoe = e - real(0.5) * rho * (v0 * v0 + v1 * v1 + v2 * v2);
        let p = mix_pressure(ar, al, rhoe);
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
