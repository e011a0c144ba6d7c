"""The swarmfield benchmark suite for airspeed velocity (asv): see docs/results/benchmarks.md, "Running the suite"."""
