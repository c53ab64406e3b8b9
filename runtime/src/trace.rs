//! Traces of a simulation (placeholder; being written).
