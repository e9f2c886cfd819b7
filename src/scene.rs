//! (scene: not written yet)
