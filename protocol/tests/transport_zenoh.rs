//! The zenoh transport: a router endpoint (the coordinator) and client endpoints exchanging
//! messages in order over several topics, large payloads intact, timeouts, a real child
//! process (the bench echo), and liveliness loss detected after SIGKILL.
//!
//! Child processes are this test binary re-executed on one test (`--exact child_entry`) with
//! an environment variable telling it which role to play. Every test uses its own port.

use protocol::transport::bench::{ECHO_SPEC_ENV, bench_transport, echo_main, echo_spec_from_env};
use protocol::transport::zenoh::{ZenohTransport, free_tcp_port, loopback_endpoint};
use protocol::transport::{Transport, TransportKind, TransportSpec};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

const CHILD_ENV: &str = "COSIM_ZENOH_TEST_CHILD";

static COUNTER: AtomicU32 = AtomicU32::new(0);

fn run_id() -> String {
    format!(
        "z{}_{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn router(run: &str) -> (ZenohTransport, String) {
    let ep = loopback_endpoint(free_tcp_port().unwrap());
    let t = ZenohTransport::open(&TransportSpec {
        kind: TransportKind::Zenoh,
        run: run.into(),
        endpoint: "coordinator".into(),
        listen: vec![ep.clone()],
        connect: vec![],
    })
    .unwrap();
    (t, ep)
}

fn client(run: &str, name: &str, ep: &str) -> ZenohTransport {
    ZenohTransport::open(&TransportSpec {
        kind: TransportKind::Zenoh,
        run: run.into(),
        endpoint: name.into(),
        listen: vec![],
        connect: vec![ep.into()],
    })
    .unwrap()
}

/// Send probes on `topic` until `to` has received one: the subscription has propagated.
fn sync(from: &mut ZenohTransport, to: &mut ZenohTransport, topic: &str) {
    let id = to.subscribe(topic).unwrap();
    let mut p = from.publisher(topic, &[]).unwrap();
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        p.send(b"probe").unwrap();
        let mut hit = false;
        to.recv(Duration::from_millis(20), &mut |i, _| hit |= i == id)
            .unwrap();
        if hit {
            break;
        }
        assert!(
            Instant::now() < end,
            "subscription on {topic} never propagated"
        );
    }
    // Drain late probes.
    while to.recv(Duration::from_millis(50), &mut |_, _| {}).unwrap() {}
}

/// Entry point of the child processes; a no-op when run as an ordinary test.
#[test]
fn child_entry() {
    if std::env::var(ECHO_SPEC_ENV).is_ok() {
        let spec = echo_spec_from_env().unwrap();
        echo_main(&spec).unwrap();
        return;
    }
    let Ok(args) = std::env::var(CHILD_ENV) else {
        return;
    };
    // "<run> <endpoint>": join the run, declare liveliness, hang.
    let mut it = args.split(' ');
    let (run, ep) = (it.next().unwrap(), it.next().unwrap());
    let mut t = client(run, "victim", ep);
    t.declare_alive().unwrap();
    println!("READY");
    std::thread::sleep(Duration::from_secs(60));
}

#[test]
fn three_topics_in_order_both_directions() {
    let run = run_id();
    let (mut coord, ep) = router(&run);
    let mut node = client(&run, "node", &ep);
    let topics = ["cosim/r/a", "cosim/r/b", "cosim/r/c"];
    for t in topics {
        node.subscribe(t).unwrap();
    }
    sync(&mut coord, &mut node, "cosim/r/sync-down");
    coord.subscribe("cosim/r/up").unwrap();
    sync(&mut node, &mut coord, "cosim/r/sync-up");

    let n = 300u32;
    let mut pubs: Vec<_> = topics
        .iter()
        .map(|t| coord.publisher(t, &["node".into()]).unwrap())
        .collect();
    for seq in 0..n {
        for (i, p) in pubs.iter_mut().enumerate() {
            let mut m = vec![i as u8; 4 + (seq as usize % 5) * 3000];
            m[..4].copy_from_slice(&seq.to_le_bytes());
            p.send(&m).unwrap();
        }
    }
    let mut got: Vec<Vec<u32>> = vec![Vec::new(); 3];
    while got.iter().map(Vec::len).sum::<usize>() < 3 * n as usize {
        let ok = node
            .recv(Duration::from_secs(10), &mut |id, b| {
                let seq = u32::from_le_bytes(b[..4].try_into().unwrap());
                assert_eq!(b.len(), 4 + (seq as usize % 5) * 3000);
                assert!(b[4..].iter().all(|&x| x as usize == id));
                got[id].push(seq);
            })
            .unwrap();
        assert!(
            ok,
            "node timed out with {:?}",
            got.iter().map(Vec::len).collect::<Vec<_>>()
        );
    }
    let expect: Vec<u32> = (0..n).collect();
    assert!(got.iter().all(|g| *g == expect));

    // And back: client → router.
    let mut up = node
        .publisher("cosim/r/up", &["coordinator".into()])
        .unwrap();
    for seq in 0..n {
        up.send(&seq.to_le_bytes()).unwrap();
    }
    let mut back = Vec::new();
    while back.len() < n as usize {
        assert!(
            coord
                .recv(Duration::from_secs(10), &mut |_, b| back
                    .push(u32::from_le_bytes(b.try_into().unwrap())))
                .unwrap()
        );
    }
    assert_eq!(back, expect);
}

#[test]
fn large_payloads_arrive_bit_exact_and_timeouts_return_false() {
    let run = run_id();
    let (mut coord, ep) = router(&run);
    let mut node = client(&run, "node", &ep);
    node.subscribe("cosim/big").unwrap();
    sync(&mut coord, &mut node, "cosim/big-sync");
    let t0 = Instant::now();
    assert!(
        !node
            .recv(Duration::from_millis(50), &mut |_, _| panic!(
                "nothing was sent"
            ))
            .unwrap()
    );
    assert!(t0.elapsed() >= Duration::from_millis(50));

    let mut p = coord.publisher("cosim/big", &["node".into()]).unwrap();
    for len in [3usize, (16 << 20) + 5, 64 << 20, 10] {
        let msg: Vec<u8> = (0..len)
            .map(|i| (i.wrapping_mul(2654435761) >> 7) as u8)
            .collect();
        p.send(&msg).unwrap();
        let mut same = false;
        assert!(
            node.recv(Duration::from_secs(20), &mut |_, got| same =
                got == msg.as_slice())
                .unwrap()
        );
        assert!(same, "payload of {len} bytes altered");
    }
}

#[test]
fn window_exchange_with_a_child_process() {
    let exe = std::env::current_exe().unwrap();
    let mut cmd = Command::new(exe);
    cmd.args(["--exact", "child_entry", "--nocapture", "--test-threads=1"])
        .stdout(Stdio::null());
    let rows = bench_transport(TransportKind::Zenoh, &[1024, 16 << 20], 3, &mut cmd).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[1].bytes, 16 << 20);
}

#[test]
fn sigkill_of_a_node_is_seen_as_lost_liveliness_within_a_second() {
    let run = run_id();
    let (mut coord, ep) = router(&run);
    let exe = std::env::current_exe().unwrap();
    let mut child = Command::new(exe)
        .args(["--exact", "child_entry", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, format!("{run} {ep}"))
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let out = child.stdout.take().unwrap();
    let ready = BufReader::new(out)
        .lines()
        .any(|l| l.map(|l| l.trim_end().ends_with("READY")).unwrap_or(false));
    if !ready {
        let _ = child.kill();
        panic!("child never got ready");
    }
    let end = Instant::now() + Duration::from_secs(5);
    while !coord.alive_endpoints().contains(&"victim".to_string()) {
        assert!(Instant::now() < end, "the child's token never arrived");
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(coord.lost_endpoints().is_empty());
    child.kill().unwrap(); // SIGKILL
    let killed = Instant::now();
    child.wait().unwrap();
    let mut lost = Vec::new();
    while lost.is_empty() && killed.elapsed() < Duration::from_secs(1) {
        lost = coord.lost_endpoints();
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(lost, vec!["victim".to_string()], "loss not seen within 1 s");
    assert!(coord.alive_endpoints().is_empty());
}
