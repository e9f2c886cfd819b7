//! (synth: not written yet)
