//! (visibility: not written yet)
