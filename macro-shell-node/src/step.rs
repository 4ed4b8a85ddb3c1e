//! The engine: central-difference time integration of seed 004 eq. 21 (M Ü = F_ext + F_c −
//! F_int) with 6 DOF per node, the stable step, and mass scaling.
//!
//! One step, t_n → t_{n+1} (the time loop on one page):
//! 1. node pass (parallel over nodes): gather the element forces at t_n (no scatter),
//!    a_n = (F_ext + F_c − F_int)/m, v_{n+½} = v_{n−½} + ½(Δt_{n−½} + Δt_{n+½}) a_n (likewise ω
//!    with the moments and the rotational inertia), impose constraints (recording the
//!    support reaction that did it), x_{n+1} = x_n + Δt v_{n+½}, rotate the nodal quaternion;
//! 2. element pass (parallel over elements): stresses from the rates at x_{n+½}, forces at
//!    x_{n+1} (`element::element_step`; elastic elements four at a time through
//!    `lanes::element_step_x4`, bit-identical);
//! 3. small sequential sums over loaded, constrained and coupled nodes: work and impulse.
//!
//! Results are bit-identical for any number of threads: every node and element writes only
//! its own entries, and all sums run in a fixed order.

use crate::element::{self, ElemInput, R_H};
use crate::lanes;
use crate::model::Model;
use mechanics::tensor::{Vector3, vec3};
use protocol::{SolverError, SolverResult};
use rayon::prelude::*;

/// Elements (and nodes) per rayon task.
const CHUNK: usize = 256;

/// Rotate a unit quaternion by the rotation vector `phi` (applied on the left, global frame).
#[inline]
fn rotate_quat(q: [f64; 4], phi: [f64; 3]) -> [f64; 4] {
    let a2 = vec3(&phi).norm_squared();
    if a2 == 0.0 {
        return q;
    }
    // cos(a/2) and sin(a/2)/a; a step turns a node by far less than 0.05 rad, where the
    // series below (truncated after a⁶) is exact to round-off (next term < 1e-18) and costs a
    // fraction of a libm sin_cos call.
    let (c, k) = if a2 < 2.5e-3 {
        (
            1.0 - a2 * (1.0 / 8.0 - a2 * (1.0 / 384.0 - a2 * (1.0 / 46080.0))),
            0.5 - a2 * (1.0 / 48.0 - a2 * (1.0 / 3840.0 - a2 * (1.0 / 645120.0))),
        )
    } else {
        let a = a2.sqrt();
        let (s, c) = (0.5 * a).sin_cos();
        (c, s / a)
    };
    let r = [c, phi[0] * k, phi[1] * k, phi[2] * k];
    let out = [
        r[0] * q[0] - r[1] * q[1] - r[2] * q[2] - r[3] * q[3],
        r[0] * q[1] + r[1] * q[0] + r[2] * q[3] - r[3] * q[2],
        r[0] * q[2] - r[1] * q[3] + r[2] * q[0] + r[3] * q[1],
        r[0] * q[3] + r[1] * q[2] - r[2] * q[1] + r[3] * q[0],
    ];
    let n = 1.0 / (out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]).sqrt();
    [out[0] * n, out[1] * n, out[2] * n, out[3] * n]
}

/// Rotate a vector by a unit quaternion.
pub fn quat_apply(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let (u, v) = (Vector3::new(q[1], q[2], q[3]), vec3(&v));
    let t = u.cross(&v) * 2.0;
    (v + t * q[0] + u.cross(&t)).into()
}

/// Rotation vector (axis × angle) of a unit quaternion.
pub fn quat_log(q: [f64; 4]) -> [f64; 3] {
    let s = (q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if s < 1e-300 {
        return [0.0; 3];
    }
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    let ang = 2.0 * s.atan2(q[0] * sign);
    let k = sign * ang / s;
    [q[1] * k, q[2] * k, q[3] * k]
}

/// Read-only data of the node pass.
struct NodePassData<'a> {
    dt: f64,
    dt_avg: f64,
    ramp: f64,
    fe: &'a [[[f64; 6]; 4]],
    offs: &'a [u32],
    adj: &'a [u32],
    mass: &'a [f64],
    inertia: &'a [f64],
    f_ext: &'a [[f64; 3]],
    f_c: &'a [[f64; 3]],
    /// Contact forces (empty without contact).
    f_k: &'a [[f64; 3]],
    m_c: &'a [[f64; 3]],
    fix: &'a [u8],
    v_pres: &'a [[f64; 3]],
}

/// The nodes of one chunk, starting at node `i0`.
#[inline(always)]
fn node_chunk(
    d: &NodePassData,
    i0: usize,
    xs: &mut [[f64; 3]],
    vs: &mut [[f64; 3]],
    ws: &mut [[f64; 3]],
    qs: &mut [[f64; 4]],
    rs: &mut [[f64; 6]],
) {
    let (dt, dt_avg, ramp) = (d.dt, d.dt_avg, d.ramp);
    for j in 0..xs.len() {
        let i = i0 + j;
        let mut f = [0.0; 6];
        for &k in &d.adj[d.offs[i] as usize..d.offs[i + 1] as usize] {
            let fk = &d.fe[(k >> 2) as usize][(k & 3) as usize];
            for c in 0..6 {
                f[c] += fk[c];
            }
        }
        let (mi, ii) = (d.mass[i], d.inertia[i]);
        let fk = d.f_k.get(i).copied().unwrap_or([0.0; 3]);
        let mut vn = [0.0; 3];
        let mut wn = [0.0; 3];
        for c in 0..3 {
            vn[c] = vs[j][c] + dt_avg * (d.f_ext[i][c] + d.f_c[i][c] + fk[c] - f[c]) / mi;
            wn[c] = ws[j][c] + dt_avg * (d.m_c[i][c] - f[3 + c]) / ii;
        }
        let bits = d.fix[i];
        // Reactions are written only where something is constrained (the entries of free
        // nodes stay zero from set-up: constraints are fixed at set-up).
        if bits != 0 {
            let mut r = [0.0; 6];
            for c in 0..3 {
                if bits & (1 << c) != 0 {
                    let target = d.v_pres[i][c] * ramp;
                    r[c] = mi * (target - vn[c]) / dt_avg;
                    vn[c] = target;
                }
                if bits & (8 << c) != 0 {
                    r[3 + c] = ii * (0.0 - wn[c]) / dt_avg;
                    wn[c] = 0.0;
                }
            }
            rs[j] = r;
        }
        vs[j] = vn;
        ws[j] = wn;
        for c in 0..3 {
            xs[j][c] += dt * vn[c];
        }
        qs[j] = rotate_quat(qs[j], [wn[0] * dt, wn[1] * dt, wn[2] * dt]);
    }
}

/// `node_chunk` compiled for AVX2 (see `element_chunk_avx2`; bit-identical results).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn node_chunk_avx2(
    d: &NodePassData,
    i0: usize,
    xs: &mut [[f64; 3]],
    vs: &mut [[f64; 3]],
    ws: &mut [[f64; 3]],
    qs: &mut [[f64; 4]],
    rs: &mut [[f64; 6]],
) {
    node_chunk(d, i0, xs, vs, ws, qs, rs)
}

/// Node pass: forces → velocities → positions. `dt_avg` = ½(Δt_{n−½} + Δt_{n+½}).
pub fn node_pass(m: &mut Model, dt: f64, dt_avg: f64, ramp: f64) {
    let d = NodePassData {
        dt,
        dt_avg,
        ramp,
        fe: &m.fe,
        offs: &m.adj_offsets,
        adj: &m.adj,
        mass: &m.mass,
        inertia: &m.inertia,
        f_ext: &m.f_ext,
        f_c: &m.f_c,
        f_k: m.contact.as_ref().map_or(&[][..], |c| &c.force[..]),
        m_c: &m.m_c,
        fix: &m.fix,
        v_pres: &m.v_pres,
    };
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    m.x.par_chunks_mut(CHUNK)
        .zip(m.v.par_chunks_mut(CHUNK))
        .zip(m.w.par_chunks_mut(CHUNK))
        .zip(m.q.par_chunks_mut(CHUNK))
        .zip(m.reaction.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, ((((xs, vs), ws), qs), rs))| {
            #[cfg(target_arch = "x86_64")]
            {
                if avx2 {
                    // SAFETY: the CPU supports AVX2 (checked at run time above), the only
                    // requirement of calling a `#[target_feature(enable = "avx2")]` function.
                    unsafe { node_chunk_avx2(&d, c * CHUNK, xs, vs, ws, qs, rs) };
                    return;
                }
            }
            node_chunk(&d, c * CHUNK, xs, vs, ws, qs, rs);
        });
}

/// Read-only data of the element pass.
struct ElemPassData<'a> {
    dt: f64,
    nip: usize,
    sec: element::Section,
    mat: element::Material,
    kc: element::ElemConst,
    x: &'a [[f64; 3]],
    v: &'a [[f64; 3]],
    w: &'a [[f64; 3]],
    conn: &'a [[u32; 4]],
    pres: &'a [f64],
}

/// One chunk of elements starting at element `e0`; returns the first degenerate element.
#[inline(always)]
fn element_chunk(
    d: &ElemPassData,
    e0: usize,
    fes: &mut [[[f64; 6]; 4]],
    st: &mut [f64],
    pl: &mut [f64],
    rs: &mut [[f64; element::RES]],
) -> Option<usize> {
    let nip = d.nip;
    let mut bad: Option<usize> = None;
    // Elastic: blocks of four elements through the four-lane kernel (bit-identical to the
    // scalar one); the scalar kernel takes the rest, a block holding a degenerate element
    // (to report it), and the J2 material.
    let mut j0 = 0;
    if d.kc.elastic {
        let nodes = lanes::NodeState {
            x: d.x,
            v: d.v,
            w: d.w,
        };
        let n3 = 3 * nip;
        while j0 + 4 <= fes.len() {
            let e = e0 + j0;
            let (s01, s23) = st[j0 * n3..(j0 + 4) * n3].split_at_mut(2 * n3);
            let (s0, s1) = s01.split_at_mut(n3);
            let (s2, s3) = s23.split_at_mut(n3);
            let [r0, r1, r2, r3] = &mut rs[j0..j0 + 4] else {
                unreachable!("a slice of 4")
            };
            let [f0, f1, f2, f3] = &mut fes[j0..j0 + 4] else {
                unreachable!("a slice of 4")
            };
            let ok = lanes::element_step_x4(
                [d.conn[e], d.conn[e + 1], d.conn[e + 2], d.conn[e + 3]],
                &nodes,
                d.dt,
                &d.sec,
                &d.kc,
                [d.pres[e], d.pres[e + 1], d.pres[e + 2], d.pres[e + 3]],
                [s0, s1, s2, s3],
                [r0, r1, r2, r3],
                [f0, f1, f2, f3],
            );
            if !ok {
                break;
            }
            j0 += 4;
        }
    }
    for j in j0..fes.len() {
        let e = e0 + j;
        let cn = d.conn[e];
        let inp = ElemInput {
            x: cn.map(|n| d.x[n as usize]),
            v: cn.map(|n| d.v[n as usize]),
            w: cn.map(|n| d.w[n as usize]),
        };
        let ok = element::element_step(
            &inp,
            d.dt,
            &d.sec,
            &d.mat,
            &d.kc,
            d.pres[e],
            &mut st[j * nip * 3..(j + 1) * nip * 3],
            &mut pl[j * nip * element::PL..(j + 1) * nip * element::PL],
            &mut rs[j],
            &mut fes[j],
        );
        if !ok && bad.is_none() {
            bad = Some(e);
        }
    }
    bad
}

/// `element_chunk` compiled for AVX2 (three-operand VEX encoding: far fewer register moves
/// in the long straight-line element kernel). No FMA contraction happens (Rust never fuses
/// a·b + c on its own), so the results are bit-identical to the baseline build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn element_chunk_avx2(
    d: &ElemPassData,
    e0: usize,
    fes: &mut [[[f64; 6]; 4]],
    st: &mut [f64],
    pl: &mut [f64],
    rs: &mut [[f64; element::RES]],
) -> Option<usize> {
    element_chunk(d, e0, fes, st, pl, rs)
}

/// Dispatch one chunk to the AVX2 build when the CPU has it.
fn element_chunk_dispatch(
    d: &ElemPassData,
    e0: usize,
    fes: &mut [[[f64; 6]; 4]],
    st: &mut [f64],
    pl: &mut [f64],
    rs: &mut [[f64; element::RES]],
) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above at run time), the only
            // requirement of calling a `#[target_feature(enable = "avx2")]` function.
            return unsafe { element_chunk_avx2(d, e0, fes, st, pl, rs) };
        }
    }
    element_chunk(d, e0, fes, st, pl, rs)
}

/// Element pass: stresses and element forces at t_{n+1}. Returns the first degenerate
/// element, if any.
pub fn element_pass(m: &mut Model, dt: f64) -> Option<usize> {
    let nip = m.section.nip;
    let d = ElemPassData {
        dt,
        nip,
        sec: m.section,
        mat: m.material,
        kc: element::ElemConst::new(&m.section, &m.material),
        x: &m.x,
        v: &m.v,
        w: &m.w,
        conn: &m.conn,
        pres: &m.pressure,
    };
    m.fe.par_chunks_mut(CHUNK)
        .zip(m.stress.par_chunks_mut(CHUNK * nip * 3))
        .zip(m.plastic.par_chunks_mut(CHUNK * nip * element::PL))
        .zip(m.res.par_chunks_mut(CHUNK))
        .enumerate()
        .map(|(c, (((fes, st), pl), rs))| element_chunk_dispatch(&d, c * CHUNK, fes, st, pl, rs))
        .reduce(
            || None,
            |a, b| match (a, b) {
                (Some(x), Some(y)) => Some(x.min(y)),
                (a, b) => a.or(b),
            },
        )
}

/// Compute the element forces of the initial state (t = 0, no motion).
pub fn initialise(m: &mut Model) -> SolverResult<()> {
    if let Some(e) = element_pass(m, 0.0) {
        return Err(SolverError::Diverged {
            time: m.time,
            reason: format!("element {e} is degenerate"),
        });
    }
    m.update_contact();
    Ok(())
}

/// One central-difference step of size `dt` (see the module notes).
pub fn step(m: &mut Model, dt: f64) -> SolverResult<()> {
    let dt_avg = if m.dt_prev > 0.0 {
        0.5 * (m.dt_prev + dt)
    } else {
        0.5 * dt
    };
    let t_mid = m.time + 0.5 * dt;
    let ramp = if m.velocity_ramp > 0.0 {
        (t_mid / m.velocity_ramp).min(1.0)
    } else {
        1.0
    };
    node_pass(m, dt, dt_avg, ramp);
    // Bookkeeping over the few special nodes, in a fixed order.
    for &i in &m.loaded_nodes {
        let i = i as usize;
        for d in 0..3 {
            m.external_work += dt * m.f_ext[i][d] * m.v[i][d];
            m.external_impulse[d] += dt_avg * m.f_ext[i][d];
            m.load_impulse[d] += dt_avg * m.f_ext[i][d];
        }
    }
    for &i in &m.constrained_nodes {
        let i = i as usize;
        for d in 0..3 {
            m.support_work += dt * m.reaction[i][d] * m.v[i][d];
            m.external_impulse[d] += dt_avg * m.reaction[i][d];
            m.support_work += dt * m.reaction[i][3 + d] * m.w[i][d];
        }
    }
    for &i in &m.coupled_nodes {
        let i = i as usize;
        // Position x_n at which the force acted (x_{n+1} − Δt v_{n+½}).
        let xn = [
            m.x[i][0] - dt * m.v[i][0],
            m.x[i][1] - dt * m.v[i][1],
            m.x[i][2] - dt * m.v[i][2],
        ];
        let tq = vec3(&xn).cross(&vec3(&m.f_c[i]));
        for d in 0..3 {
            m.interface_angular_impulse[d] += dt_avg * (tq[d] + m.m_c[i][d]);
            m.interface_work += dt * (m.f_c[i][d] * m.v[i][d] + m.m_c[i][d] * m.w[i][d]);
            m.interface_impulse[d] += dt_avg * m.f_c[i][d];
        }
    }
    if let Some(e) = element_pass(m, dt) {
        return Err(SolverError::Diverged {
            time: m.time + dt,
            reason: format!("element {e} became degenerate (inverted or zero area)"),
        });
    }
    // Contact forces at x_{n+1}, for the next node pass.
    m.update_contact();
    m.time += dt;
    m.dt_prev = dt;
    m.steps += 1;
    Ok(())
}

/// Element estimates [membrane, transverse, rotational] at the current geometry.
fn element_estimates(m: &Model) -> Vec<[f64; 3]> {
    let sec = m.section;
    let mat = m.material;
    (0..m.num_elements())
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|e| {
            let x = m.conn[e].map(|n| m.x[n as usize]);
            match element::geometry(&x) {
                Some(g) => element::stiffness_estimates(&sec, &mat, m.res[e][R_H], &g),
                None => [f64::INFINITY; 3],
            }
        })
        .collect()
}

/// Squared frequency bound of node `i` (see `element::stiffness_estimates`), with the
/// coupling stiffness on the translations: max((Σs_m + k)/m, (Σs_w + k)/m + Σs_θ/I).
fn node_omega2(m: &Model, est: &[[f64; 3]], i: usize) -> f64 {
    let mut s = [0.0; 3];
    for &k in &m.adj[m.adj_offsets[i] as usize..m.adj_offsets[i + 1] as usize] {
        let r = &est[(k >> 2) as usize];
        for c in 0..3 {
            s[c] += r[c];
        }
    }
    let kc = m.k_c[i] + m.contact.as_ref().map_or(0.0, |c| c.k_max);
    ((s[0] + kc) / m.mass[i]).max((s[1] + kc) / m.mass[i] + s[2] / m.inertia[i])
}

/// The stable step now: dt_scale · 2/ω_max over all nodes (coupling stiffness included).
pub fn stable_dt(m: &Model) -> f64 {
    let est = element_estimates(m);
    let w2 = (0..m.num_nodes())
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|i| node_omega2(m, &est, i))
        .reduce(|| 0.0, f64::max);
    if w2 > 0.0 {
        m.dt_scale * 2.0 / w2.sqrt()
    } else {
        f64::INFINITY
    }
}

/// Mass scaling to the target step. A node's squared frequency is bounded by
/// max((Σs_m + k_c)/m, (Σs_w + k_c)/m + Σs_θ/I) (`node_omega2`); where that exceeds the
/// target, the translational mass is raised only as far as the translational terms need,
/// m' = max(m, (Σs_m + k_c)/ω_t²), and — when the bending branch is still too high — to at
/// most half of that branch's budget, m' ≥ 2(Σs_w + k_c)/ω_t², and the rest is taken by the
/// rotary inertia, I' = max(I, Σs_θ/(ω_t² − (Σs_w + k_c)/m')) (rotary-inertia scaling). Scaling
/// m and I by one common factor instead lets the rotational branch of a thick shell on small
/// elements — or of a node carrying a joint's coupling mass — multiply translational mass
/// (and with it the inertia of the structure and the coupling) by orders of magnitude.
/// Returns the added translational mass (kg); also accumulated in `added_mass` /
/// `added_inertia`.
pub fn apply_mass_scaling(m: &mut Model, target_dt: f64) -> f64 {
    let est = element_estimates(m);
    let w_t = m.dt_scale * 2.0 / target_dt;
    let w2t = w_t * w_t;
    let mut added = 0.0;
    let mut added_i = 0.0;
    for i in 0..m.num_nodes() {
        if node_omega2(m, &est, i) <= w2t {
            continue;
        }
        let mut s = [0.0; 3];
        for &k in &m.adj[m.adj_offsets[i] as usize..m.adj_offsets[i + 1] as usize] {
            let r = &est[(k >> 2) as usize];
            for c in 0..3 {
                s[c] += r[c];
            }
        }
        let kc = m.k_c[i] + m.contact.as_ref().map_or(0.0, |c| c.k_max);
        let (m0, i0) = (m.mass[i], m.inertia[i]);
        let mut m1 = m0.max((s[0] + kc) / w2t);
        let mut i1 = i0;
        if (s[1] + kc) / m1 + s[2] / i0 > w2t {
            if (s[1] + kc) / m1 > 0.5 * w2t {
                m1 = 2.0 * (s[1] + kc) / w2t;
            }
            let room = w2t - (s[1] + kc) / m1;
            i1 = i0.max(s[2] / room);
        }
        m.mass[i] = m1;
        m.inertia[i] = i1;
        added += m1 - m0;
        added_i += i1 - i0;
    }
    m.added_mass += added;
    m.added_inertia += added_i;
    added
}

/// Sub-steps for a span: the fewest uniform steps no larger than the stable step (a step
/// longer by less than 0.1 % is accepted — the safety factor `dt_scale` covers it — so a
/// window sized to the stable step stays one step while the mesh moves). Returns
/// (count, step).
pub fn plan(m: &Model, span: f64) -> SolverResult<(u64, f64)> {
    let dt_s = stable_dt(m);
    if !(dt_s.is_finite() && dt_s > 0.0) {
        return Err(SolverError::Diverged {
            time: m.time,
            reason: format!("stable step is {dt_s}"),
        });
    }
    let n = (span / dt_s * (1.0 - 1e-3)).ceil().max(1.0) as u64;
    Ok((n, span / n as f64))
}

/// Take `n` steps of `dt` from `t0`, landing the clock exactly on t0 + n·dt.
pub fn run_steps(m: &mut Model, t0: f64, n: u64, dt: f64) -> SolverResult<()> {
    for k in 0..n {
        step(m, dt)?;
        m.time = t0 + dt * (k + 1) as f64;
    }
    Ok(())
}

/// Advance exactly to `t_end` with uniform sub-steps no larger than the stable step.
/// Returns the number of steps taken.
pub fn advance_to(m: &mut Model, t_end: f64) -> SolverResult<u64> {
    let span = t_end - m.time;
    if span <= 0.0 {
        return Ok(0);
    }
    let (n, dt) = plan(m, span)?;
    let t0 = m.time;
    run_steps(m, t0, n, dt)?;
    m.time = t_end;
    Ok(n)
}
