//! (run: not written yet)
