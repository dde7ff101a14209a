//! The measurement lab (not published): the trace-driven streaming simulator behind the papers'
//! tables, the generated cities, and the shared code of the benches and examples.

pub mod city;
pub mod experiments;
pub mod sim;
