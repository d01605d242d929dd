"""Analysis tools beside the runs: the lateral loop's margins (`ld3 control report`) and the benchmarks (`ld3
bench`)."""
