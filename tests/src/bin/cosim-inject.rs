//! Test helper: publishes malformed bytes on a topic of a running co-simulation, as a faulty
//! or hostile participant would.

use protocol::transport::{self, TransportKind, TransportSpec};
use std::time::{Duration, Instant};

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(run), Some(kind), Some(topic)) = (
        arg(&args, "--run"),
        arg(&args, "--transport"),
        arg(&args, "--topic"),
    ) else {
        eprintln!(
            "usage: cosim-inject --run RUN --transport shm|zenoh --topic TOPIC [--readers a,b] [--connect EP]"
        );
        std::process::exit(2);
    };
    let kind: TransportKind = match kind.parse() {
        Ok(k) => k,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let readers: Vec<String> = arg(&args, "--readers")
        .map(|r| r.split(',').map(str::to_string).collect())
        .unwrap_or_default();
    let spec = TransportSpec {
        kind,
        run,
        endpoint: "intruder".into(),
        listen: vec![],
        connect: arg(&args, "--connect").into_iter().collect(),
    };
    let result = (|| -> Result<(), Box<dyn std::error::Error>> {
        let mut t = transport::open(&spec)?;
        let mut p = t.publisher(&topic, &readers)?;
        let start = Instant::now();
        while t.readers(&topic) == Some(0) && start.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(5));
        }
        for _ in 0..3 {
            p.send(b"this is not a cosim message")?;
            std::thread::sleep(Duration::from_millis(20));
        }
        // Leave as a participant should: ports closed, then the run's leftovers swept
        // (a no-op while the run is still alive).
        drop(p);
        drop(t);
        transport::cleanup(spec.kind, &spec.run);
        Ok(())
    })();
    if let Err(e) = result {
        eprintln!("cosim-inject: {e}");
        std::process::exit(1);
    }
}
