//! Shared output helpers: frame writers, stats.jsonl, summary.json (being filled in).
