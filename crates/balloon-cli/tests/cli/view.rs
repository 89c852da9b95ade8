//! Tests of `balloon view` (issue 7; being written).
