//! Post-processing: the quantities of `history.csv` and `summary.json`, the profiles, and the
//! statistics of periodic quantities and of driven cycles.
pub mod cycles;
pub mod open_area;
pub mod oscillation;
pub mod quantities;
