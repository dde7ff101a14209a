//! The lab's integration tests in one executable: the simulator, its scoring and the
//! `splat2tiles-lab simulate` command.

#[path = "../../../../tests/common/mod.rs"]
mod common;

mod module_cycles;
mod sim_city;
mod sim_score;
mod sim_session;
mod simulate_tool;
