"""The paper's experiments: the named campaigns (`ld3 campaign NAME`), the security margin, the demo and `ld3 paper`
with the paper's values."""
