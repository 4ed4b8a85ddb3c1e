//! The C ABI driven in-process, with callbacks written in Rust as a C solver would write them:
//! parameters, description, mesh, fields in and out without copies, errors with their key,
//! and calls a careless C caller makes (NULL, bad UTF-8, the wrong callback) that must give
//! an error, never a panic.

use cosim_participant::*;
use protocol::{Binding, CouplingKind, FieldSet, Role, Solver, Window};
use std::ffi::{CStr, c_char, c_int, c_void};

/// What the test solver remembers.
#[derive(Default)]
struct State {
    points: i64,
    scale: f64,
    name: String,
    destroyed: bool,
    /// Behaviour switch: 1 = advance without reporting why it failed, 2 = outbox put from
    /// describe (not allowed), 3 = read a parameter with the wrong type.
    mode: i64,
}

fn state<'a>(user: *mut c_void) -> &'a mut State {
    // SAFETY: every test passes a live `State`.
    unsafe { &mut *(user as *mut State) }
}

unsafe extern "C" fn create(
    user: *mut c_void,
    model: *const c_char,
    call: *mut CosimCall,
) -> c_int {
    let s = state(user);
    // SAFETY: the runtime passes a C string.
    assert_eq!(unsafe { CStr::from_ptr(model) }.to_str(), Ok("toy"));
    unsafe {
        if cosim_param_i64(call, c"points".as_ptr(), &mut s.points) != COSIM_OK {
            return 1;
        }
        if cosim_param_f64(call, c"scale".as_ptr(), &mut s.scale) == COSIM_MISSING {
            s.scale = 1.0;
        }
        cosim_param_i64(call, c"mode".as_ptr(), &mut s.mode);
        let mut name: *const c_char = std::ptr::null();
        if cosim_param_str(call, c"faces.a".as_ptr(), &mut name) == COSIM_OK {
            s.name = CStr::from_ptr(name).to_string_lossy().into_owned();
        }
        if s.mode == 3 {
            let mut x = 0.0;
            return c_int::from(cosim_param_f64(call, c"faces.a".as_ptr(), &mut x) != COSIM_OK);
        }
    }
    0
}

unsafe extern "C" fn describe(user: *mut c_void, call: *mut CosimCall) -> c_int {
    let s = state(user);
    unsafe {
        cosim_describe_model(call, c"toy".as_ptr(), std::ptr::null());
        cosim_describe_interface(
            call,
            c"a".as_ptr(),
            s.points as usize,
            c"force".as_ptr(),
            c"velocity, position".as_ptr(),
        );
        if s.mode == 2 {
            // Not allowed here: recorded as the callback's error even though we return 0.
            cosim_outbox_put(call, c"a".as_ptr(), c"force".as_ptr(), 3, 1);
        }
    }
    0
}

unsafe extern "C" fn mesh(user: *mut c_void, _name: *const c_char, call: *mut CosimCall) -> c_int {
    let s = state(user);
    let xyz: Vec<f64> = (0..s.points).flat_map(|i| [i as f64, 0.0, 0.0]).collect();
    unsafe { cosim_mesh_points(call, xyz.as_ptr(), s.points as usize) }
}

unsafe extern "C" fn stable_dt(_user: *mut c_void) -> f64 {
    0.25
}

unsafe extern "C" fn advance(
    user: *mut c_void,
    w: *const CosimWindow,
    call: *mut CosimCall,
    r: *mut CosimStepReport,
) -> c_int {
    let s = state(user);
    if s.mode == 1 {
        return 7;
    }
    unsafe {
        let mut len = 0usize;
        let mut comps = 0u32;
        let v = cosim_inbox_get(
            call,
            c"a".as_ptr(),
            c"velocity".as_ptr(),
            &mut comps,
            &mut len,
        );
        if v.is_null() {
            cosim_set_error(
                call,
                CosimErrorKind::Interface,
                c"a".as_ptr(),
                c"no velocity".as_ptr(),
            );
            return 1;
        }
        assert_eq!(comps, 3);
        let f = cosim_outbox_put(call, c"a".as_ptr(), c"force".as_ptr(), 3, s.points as usize);
        for i in 0..len {
            *f.add(i) = -s.scale * *v.add(i);
        }
        cosim_report_scalar(call, c"window".as_ptr(), (*w).index as f64);
        (*r).kinetic_energy = 2.5;
        (*r).momentum = [1.0, 2.0, 3.0];
        (*r).substeps = 4;
    }
    0
}

unsafe extern "C" fn destroy(user: *mut c_void) {
    state(user).destroyed = true;
}

fn vtable() -> CosimSolverVTable {
    CosimSolverVTable {
        abi_version: COSIM_ABI_VERSION,
        create: Some(create),
        describe: Some(describe),
        interface_mesh: Some(mesh),
        setup: None,
        stable_dt: Some(stable_dt),
        advance: Some(advance),
        write_output: None,
        save_state: None,
        load_state: None,
        destroy: Some(destroy),
    }
}

fn params(s: &str) -> toml::Table {
    toml::from_str(s).unwrap()
}

fn build(st: &mut State, p: &str) -> protocol::SolverResult<Box<dyn Solver>> {
    solver_from_vtable(vtable(), st as *mut State as *mut c_void, "toy", &params(p))
}

#[test]
fn a_c_solver_reads_params_describes_and_exchanges_fields_without_copies() {
    let mut st = State::default();
    let mut s = build(&mut st, "points = 2\nscale = 3\nfaces = { a = \"left\" }").unwrap();
    let d = s.describe();
    assert_eq!(d.model, "toy");
    assert_eq!(d.interfaces[0].points, 2);
    assert_eq!(d.interfaces[0].accepts, ["velocity", "position"]);
    let m = s.interface("a").unwrap();
    assert_eq!(m.positions, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
    assert_eq!(s.stable_dt(), 0.25);
    let b = Binding {
        coupling: "c".into(),
        kind: CouplingKind::Kinematic,
        interface: "a".into(),
        role: Role::Responder,
        peer: "p".into(),
        peer_interface: "b".into(),
        sends: vec!["force".into()],
        receives: vec!["velocity".into()],
        input_lag: 0,
    };
    let mut inbox = FieldSet::new();
    let mut out = FieldSet::new();
    s.setup(&[b], &inbox, &mut out).unwrap();
    inbox
        .put("a", "velocity", 3, 2)
        .copy_from_slice(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    let w = Window {
        index: 7,
        t0: 0.0,
        t1: 1.0,
        write_output: false,
    };
    let r = s.advance(&w, &inbox, &mut out).unwrap();
    assert_eq!(
        out.require("a", "force", 6).unwrap(),
        [-3.0, -6.0, -9.0, -12.0, -15.0, -18.0]
    );
    assert_eq!(r.kinetic_energy, 2.5);
    assert_eq!(r.momentum, [1.0, 2.0, 3.0]);
    assert_eq!(r.substeps, 4);
    assert_eq!(r.scalars, [("window".to_string(), 7.0)]);
    // The outbox buffer is reused: the next window writes into the same memory.
    let before = out.require("a", "force", 6).unwrap().as_ptr();
    s.advance(&w, &inbox, &mut out).unwrap();
    assert_eq!(out.require("a", "force", 6).unwrap().as_ptr(), before);
    assert!(
        s.save_state().is_err(),
        "no save_state callback: cannot checkpoint"
    );
    drop(s);
    assert!(st.destroyed, "destroy runs when the solver is dropped");
    assert_eq!(st.name, "left");
}

#[test]
fn errors_name_their_key_or_callback() {
    let mut st = State::default();
    let e = build(&mut st, "points = 1\npionts = 2")
        .err()
        .unwrap()
        .to_string();
    assert_eq!(
        e,
        "pionts: unknown parameter (this solver reads: faces, mode, points, scale)"
    );
    let e = build(&mut State::default(), "points = \"two\"")
        .err()
        .unwrap()
        .to_string();
    assert_eq!(e, "points: must be an integer, got string");
    let e = build(
        &mut State::default(),
        "points = 1\nmode = 3\nfaces = { a = \"x\" }",
    )
    .err()
    .unwrap()
    .to_string();
    assert_eq!(e, "faces.a: must be a number, got string");
    let e = build(&mut State::default(), "points = 1\nmode = 2")
        .err()
        .unwrap()
        .to_string();
    assert_eq!(e, "cosim_outbox_put: in setup and advance only");
    let mut st = State::default();
    let mut s = build(&mut st, "points = 1\nmode = 1").unwrap();
    let w = Window {
        index: 1,
        t0: 0.0,
        t1: 1.0,
        write_output: false,
    };
    let e = s
        .advance(&w, &FieldSet::new(), &mut FieldSet::new())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "advance returned 7 without a message (cosim_set_error)");
    let mut st = State::default();
    let mut s = build(&mut st, "points = 1").unwrap();
    let e = s
        .advance(&w, &FieldSet::new(), &mut FieldSet::new())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "interface a: no velocity");
}

#[test]
fn careless_calls_give_errors_not_panics() {
    unsafe {
        // No call handle at all.
        assert_eq!(cosim_warn(std::ptr::null_mut(), c"x".as_ptr()), COSIM_ERROR);
        assert!(
            cosim_outbox_put(std::ptr::null_mut(), c"a".as_ptr(), c"f".as_ptr(), 1, 1).is_null()
        );
        cosim_set_error(
            std::ptr::null_mut(),
            CosimErrorKind::Other,
            std::ptr::null(),
            std::ptr::null(),
        );
        assert_eq!(cosim_binding_count(std::ptr::null_mut()), 0);
        // A handle, but NULL or invalid strings, NULL out pointers, absurd sizes.
        let c = Box::into_raw(Box::new(CosimCall::bare("advance")));
        assert!(
            cosim_inbox_get(
                c,
                std::ptr::null(),
                c"f".as_ptr(),
                std::ptr::null_mut(),
                std::ptr::null_mut()
            )
            .is_null()
        );
        assert_eq!(
            (*c).outcome(0).unwrap_err().to_string(),
            "advance: interface is NULL"
        );
        let bad = [0xffu8, 0xfe, 0];
        assert!(cosim_outbox_put(c, bad.as_ptr().cast(), c"f".as_ptr(), 1, 1).is_null());
        assert_eq!(
            (*c).outcome(0).unwrap_err().to_string(),
            "advance: interface is not UTF-8"
        );
        let mut out = FieldSet::new();
        (*c).lend_outbox(&mut out as *mut FieldSet);
        assert!(cosim_outbox_put(c, c"a".as_ptr(), c"f".as_ptr(), 1, usize::MAX).is_null());
        assert!(
            (*c).outcome(0)
                .unwrap_err()
                .to_string()
                .contains("too many")
        );
        assert!(cosim_outbox_put(c, c"a".as_ptr(), c"f".as_ptr(), 0, 1).is_null());
        assert!((*c).outcome(0).is_err());
        assert_eq!(cosim_mesh_points(c, std::ptr::null(), 3), COSIM_ERROR);
        assert_eq!(
            (*c).outcome(0).unwrap_err().to_string(),
            "advance: xyz is NULL"
        );
        assert_eq!(cosim_binding_get(c, 0, std::ptr::null_mut()), COSIM_MISSING);
        assert_eq!(
            cosim_param_f64(c, c"x".as_ptr(), std::ptr::null_mut()),
            COSIM_ERROR
        );
        assert_eq!(
            (*c).outcome(0).unwrap_err().to_string(),
            "advance: parameters are read in create only"
        );
        // The first error of a call is the one reported.
        cosim_set_error(c, CosimErrorKind::Config, c"k".as_ptr(), c"first".as_ptr());
        cosim_set_error(c, CosimErrorKind::Config, c"k".as_ptr(), c"second".as_ptr());
        assert_eq!((*c).outcome(1).unwrap_err().to_string(), "k: first");
        drop(Box::from_raw(c));
    }
    // A vtable of another ABI version or missing a required callback is refused.
    let mut vt = vtable();
    vt.abi_version = 99;
    let e = solver_from_vtable(vt, std::ptr::null_mut(), "toy", &params(""))
        .err()
        .unwrap();
    assert!(e.to_string().contains("ABI version 99"), "{e}");
    let mut vt = vtable();
    vt.advance = None;
    let e = solver_from_vtable(vt, std::ptr::null_mut(), "toy", &params(""))
        .err()
        .unwrap();
    assert!(e.to_string().contains("advance"), "{e}");
}

#[test]
fn node_main_refuses_a_null_vtable_and_a_bad_command_line() {
    let argv = [c"toy".as_ptr(), c"--bogus".as_ptr()];
    // SAFETY: a valid argv; a NULL vtable is refused before anything else.
    assert_eq!(
        unsafe { cosim_node_main(2, argv.as_ptr(), std::ptr::null(), std::ptr::null_mut()) },
        2
    );
    let vt = vtable();
    let mut st = State::default();
    // SAFETY: valid argv and vtable; the command line lacks --run and --node.
    let code = unsafe { cosim_node_main(2, argv.as_ptr(), &vt, (&mut st as *mut State).cast()) };
    assert_eq!(code, 2);
}
