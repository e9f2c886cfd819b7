//! (observe: not written yet)
