//! (haar: not written yet)
