//! Analysis several experiments share (each experiment's own is in its file).

pub(super) mod hertz;
pub(super) mod pareto;
