//! Integration tests, compiled as one binary (one module per topic).

mod util;

mod accuracy;
mod analytic;
mod bad_input;
mod batch;
mod cli;
mod clip;
mod colormap;
mod confine;
mod depth_cue;
mod determinism;
mod exit_codes;
mod fit;
mod formats;
mod formats_hostile;
mod formats_tiff;
mod fuzz;
mod geometry;
mod hard_cases;
mod histogram;
mod keyframes;
mod mapping;
mod memory;
mod nrrd;
mod one_scene_per_folder;
mod output_folder;
mod overflow;
mod overlay;
mod presets;
mod resume_trust;
mod skipping;
mod special_files;
mod stereo;
mod units;
mod viewer;
