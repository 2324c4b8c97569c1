//! End-to-end test helpers (work in progress).
