//! (reference: not written yet)
