//! Live browser viewer (placeholder; being written for issue 7).
