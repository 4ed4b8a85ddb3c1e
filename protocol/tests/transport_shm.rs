//! The iceoryx2 shared-memory transport: ordered delivery over several topics with
//! backpressure instead of loss, large payloads intact, timeouts, a `Send` publisher, a real
//! child process (the bench echo), and crash cleanup after SIGKILL.
//!
//! Child processes are this test binary re-executed on one test (`--exact <name>`) with an
//! environment variable telling it which role to play.

use protocol::transport::bench::{ECHO_SPEC_ENV, bench_transport, echo_main, echo_spec_from_env};
use protocol::transport::shm::{ShmTransport, cleanup_run, prefix, shm_files};
use protocol::transport::{Transport, TransportKind, TransportSpec};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const CHILD_ENV: &str = "COSIM_SHM_TEST_CHILD";

static COUNTER: AtomicU32 = AtomicU32::new(0);

fn run_id() -> String {
    format!(
        "s{}_{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn spec(run: &str, endpoint: &str) -> TransportSpec {
    TransportSpec {
        kind: TransportKind::Shm,
        run: run.into(),
        endpoint: endpoint.into(),
        listen: vec![],
        connect: vec![],
    }
}

fn wait_for_reader(t: &dyn Transport, topic: &str) {
    let end = Instant::now() + Duration::from_secs(10);
    while t.readers(topic) != Some(1) {
        assert!(Instant::now() < end, "no reader on {topic}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Entry point of the child processes; a no-op when run as an ordinary test.
#[test]
fn child_entry() {
    if std::env::var(ECHO_SPEC_ENV).is_ok() {
        let spec = echo_spec_from_env().unwrap();
        echo_main(&spec).unwrap();
        return;
    }
    let Ok(run) = std::env::var(CHILD_ENV) else {
        return;
    };
    // Crash victim: hold a publisher (with a sample in flight) and a subscriber, then hang.
    let mut t = ShmTransport::open(&spec(&run, "victim")).unwrap();
    t.subscribe("cosim/x/in").unwrap();
    let mut p = t.publisher("cosim/x/out", &["nobody".into()]).unwrap();
    p.send(&vec![7u8; 1 << 20]).unwrap();
    println!("READY");
    std::thread::sleep(Duration::from_secs(60));
}

#[test]
fn three_topics_arrive_complete_and_in_order_despite_a_small_buffer() {
    let run = run_id();
    let topics = ["cosim/t/a", "cosim/t/b", "cosim/t/c"];
    let n = 200u32; // far more than the subscriber buffer: the sender must block, not drop
    let (ready_tx, ready_rx) = mpsc::channel();
    let run2 = run.clone();
    let reader = std::thread::spawn(move || {
        let mut b = ShmTransport::open(&spec(&run2, "b")).unwrap();
        for t in topics {
            b.subscribe(t).unwrap();
        }
        ready_tx.send(()).unwrap();
        let mut got: Vec<Vec<u32>> = vec![Vec::new(); 3];
        while got.iter().map(Vec::len).sum::<usize>() < 3 * n as usize {
            let ok = b
                .recv(Duration::from_secs(10), &mut |id, bytes| {
                    let seq = u32::from_le_bytes(bytes[..4].try_into().unwrap());
                    // Sizes vary per message so the segments must grow underneath.
                    assert_eq!(bytes.len(), 4 + (seq as usize % 7) * 1000 + id);
                    got[id].push(seq);
                })
                .unwrap();
            assert!(
                ok,
                "reader timed out: {:?}",
                got.iter()
                    .map(|g| (g.len(), g.last().copied()))
                    .collect::<Vec<_>>()
            );
        }
        // Nothing more is queued.
        assert!(
            !b.recv(Duration::from_millis(20), &mut |_, _| panic!(
                "extra message"
            ))
            .unwrap()
        );
        got
    });
    ready_rx.recv().unwrap();
    let mut a = ShmTransport::open(&spec(&run, "a")).unwrap();
    let mut pubs: Vec<_> = topics
        .iter()
        .map(|t| a.publisher(t, &["b".into()]).unwrap())
        .collect();
    for t in topics {
        wait_for_reader(&a, t);
    }
    // Topic c is written from another thread, as a node's heartbeat thread would.
    let mut pc = pubs.pop().unwrap();
    let heartbeat = std::thread::spawn(move || {
        for seq in 0..n {
            let mut m = vec![0u8; 4 + (seq as usize % 7) * 1000 + 2];
            m[..4].copy_from_slice(&seq.to_le_bytes());
            pc.send(&m).unwrap();
        }
    });
    for seq in 0..n {
        for (id, p) in pubs.iter_mut().enumerate() {
            let mut m = vec![0u8; 4 + (seq as usize % 7) * 1000 + id];
            m[..4].copy_from_slice(&seq.to_le_bytes());
            p.send(&m).unwrap();
        }
    }
    heartbeat.join().unwrap();
    let got = reader.join().unwrap();
    let expect: Vec<u32> = (0..n).collect();
    for g in &got {
        assert_eq!(g, &expect);
    }
    drop(pubs);
    drop(a);
    cleanup_run(&run);
    assert!(
        shm_files(&run).is_empty(),
        "left behind: {:?}",
        shm_files(&run)
    );
}

#[test]
fn large_payloads_arrive_bit_exact_and_timeouts_return_false() {
    let run = run_id();
    let mut b = ShmTransport::open(&spec(&run, "b")).unwrap();
    b.subscribe("cosim/big").unwrap();
    let mut a = ShmTransport::open(&spec(&run, "a")).unwrap();
    let mut p = a.publisher("cosim/big", &["b".into()]).unwrap();
    assert_eq!(a.readers("cosim/big"), Some(1));
    assert_eq!(a.readers("cosim/nobody-reads-this"), Some(0));

    let t0 = Instant::now();
    assert!(
        !b.recv(Duration::from_millis(50), &mut |_, _| panic!(
            "nothing was sent"
        ))
        .unwrap()
    );
    assert!(t0.elapsed() >= Duration::from_millis(50));

    for len in [3usize, (16 << 20) + 5, 64 << 20, 10] {
        let msg: Vec<u8> = (0..len)
            .map(|i| (i.wrapping_mul(2654435761) >> 7) as u8)
            .collect();
        p.send(&msg).unwrap();
        let mut same = false;
        assert!(
            b.recv(Duration::from_secs(10), &mut |_, got| same =
                got == msg.as_slice())
                .unwrap()
        );
        assert!(same, "payload of {len} bytes altered");
    }
    drop(p);
    drop(a);
    drop(b);
    cleanup_run(&run);
    assert!(shm_files(&run).is_empty());
}

#[test]
fn window_exchange_with_a_child_process() {
    // Advance → Fields (16 MiB of f64, checked on arrival) + Done, through a real child.
    let exe = std::env::current_exe().unwrap();
    let mut cmd = Command::new(exe);
    cmd.args(["--exact", "child_entry", "--nocapture", "--test-threads=1"])
        .stdout(Stdio::null());
    let rows = bench_transport(TransportKind::Shm, &[1024, 16 << 20], 3, &mut cmd).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[1].bytes, 16 << 20);
    assert!(
        rows.iter()
            .all(|r| r.median_us > 0.0 && r.p10_us <= r.p90_us)
    );
}

#[test]
fn sigkilled_child_leaves_nothing_in_dev_shm_after_cleanup() {
    let run = run_id();
    let exe = std::env::current_exe().unwrap();
    let mut child = Command::new(exe)
        .args(["--exact", "child_entry", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, &run)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let out = child.stdout.take().unwrap();
    let mut ready = false;
    for line in BufReader::new(out).lines() {
        if line.unwrap().trim_end().ends_with("READY") {
            ready = true;
            break;
        }
    }
    assert!(ready, "child never got ready");
    let files = shm_files(&run);
    assert!(
        files.len() >= 3,
        "expected the child's segments with prefix {} in /dev/shm, found {files:?}",
        prefix(&run)
    );
    child.kill().unwrap(); // SIGKILL: no destructor runs
    child.wait().unwrap();
    assert!(!shm_files(&run).is_empty(), "the kill itself cleaned up?");
    let cleaned = cleanup_run(&run);
    assert!(cleaned >= 1, "the dead node was not recognised");
    assert!(
        shm_files(&run).is_empty(),
        "left behind: {:?}",
        shm_files(&run)
    );
}
