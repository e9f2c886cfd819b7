//! (estimate: not written yet)
