//! The streaming experiments behind `splat2tiles-lab simulate`: the papers' tables on the shared
//! scenes, the generated city and layered content, written as Markdown, CSV and SVG plots.

pub mod simulate;
pub mod simulate_city;
mod simulate_layers;
