//! (trace: not written yet)
