//! Post-processing: the quantities of `history.csv` and `summary.json`, and the profiles.
pub mod quantities;
