//! Transport benchmark (docs/architecture.md): the round trip of one coupling window over shm,
//! zenoh and the in-process transport, each against a real echo process (this example
//! re-executed with `--echo`).
//!
//! `cargo run --release -p protocol --example transport_bench -- [--transport shm|zenoh|local|all]
//!  [--rounds N] [--sizes 1024,65536,...] [--iox-variants]`

use protocol::transport::TransportKind;
use protocol::transport::bench::{
    BenchTable, DEFAULT_SIZES, bench_transport, echo_main, echo_spec_from_env,
    iceoryx_variant_rtt_us,
};
use std::process::Command;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "--echo") {
        let spec = echo_spec_from_env()?;
        echo_main(&spec)?;
        return Ok(());
    }
    let mut kinds = vec![
        TransportKind::Shm,
        TransportKind::Zenoh,
        TransportKind::Local,
    ];
    let mut rounds = 200;
    let mut sizes = DEFAULT_SIZES.to_vec();
    let mut variants = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || {
            it.next()
                .cloned()
                .ok_or_else(|| anyhow::anyhow!("{a} needs a value"))
        };
        match a.as_str() {
            "--transport" => {
                let v = value()?;
                if v != "all" {
                    kinds = vec![v.parse().map_err(anyhow::Error::msg)?];
                }
            }
            "--iox-variants" => variants = true,
            "--rounds" => rounds = value()?.parse()?,
            "--sizes" => {
                sizes = value()?
                    .split(',')
                    .map(|s| s.trim().parse::<usize>())
                    .collect::<Result<_, _>>()?
            }
            other => anyhow::bail!("unknown argument {other}"),
        }
    }
    let exe = std::env::current_exe()?;
    let mut rows = Vec::new();
    for kind in kinds {
        let mut cmd = Command::new(&exe);
        cmd.arg("--echo");
        rows.extend(bench_transport(kind, &sizes, rounds, &mut cmd)?);
        eprintln!("{} done", kind.as_str());
    }
    println!("{}", BenchTable(&rows));
    if variants {
        use iceoryx2::prelude::{ipc, ipc_threadsafe};
        println!("| raw iceoryx2 round trip, two threads | ipc µs | ipc_threadsafe µs |");
        println!("|---|---:|---:|");
        for &b in &sizes {
            let a = iceoryx_variant_rtt_us::<ipc::Service>(b, b, rounds)?;
            let t = iceoryx_variant_rtt_us::<ipc_threadsafe::Service>(b, b, rounds)?;
            println!("| {b} B | {a:.1} | {t:.1} |");
        }
    }
    Ok(())
}
