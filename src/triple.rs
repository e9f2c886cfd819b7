//! (triple: not written yet)
