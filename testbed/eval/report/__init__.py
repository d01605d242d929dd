"""Reports over finished runs: comparison tables, summary statistics, figures drawn later, the DRP before/after
figure."""
