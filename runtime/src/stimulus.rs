//! Built-in key stimuli (placeholder; being written).
