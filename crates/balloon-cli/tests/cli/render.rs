//! Tests of `balloon render` (issue 7; being written).
