//! (transport: not written yet)
