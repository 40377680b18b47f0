//! NRRD reader/writer against files written by teem and pynrrd.
