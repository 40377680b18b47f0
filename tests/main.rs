//! Integration tests, compiled as one binary (one module per topic).

mod util;

mod analytic;
mod cli;
mod determinism;
mod nrrd;
