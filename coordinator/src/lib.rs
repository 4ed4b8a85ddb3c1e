//! The cosim coordinator (the master of docs/architecture.md): case config, launcher and window
//! scheduler, MCAP recorder, replay and the `cosim` command line. It owns the clock, the
//! schedule, the recording and the failure handling; it never does physics.

pub mod books;
pub mod case;
pub mod charts;
pub mod checkpoint;
pub mod cli;
pub mod clock;
pub mod conformance;
pub mod contract;
pub mod deadlock;
pub mod engine;
pub mod export;
pub mod fields;
pub mod guard;
pub mod histogram;
pub mod info;
pub mod integrity;
pub mod joints;
pub mod launch;
pub mod lock;
pub mod nest;
pub mod params;
pub mod plot;
pub mod profile;
pub mod progress;
pub mod record;
pub mod replay;
pub mod run;
