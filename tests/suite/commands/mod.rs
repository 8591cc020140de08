//! The real binaries end to end: commands, hostile arguments, the docs a user reads, the
//! generators, the farm scripts, the benchmark scenes.

mod bench_scenes;
mod cli;
mod cli_hostile;
mod denoise;
mod docs;
mod exr_header;
mod generators;
mod pipeline;
mod slurm;
