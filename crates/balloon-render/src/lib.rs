//! Software rendering of simulation frames (placeholder; being written for issue 7).
