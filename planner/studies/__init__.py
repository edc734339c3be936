"""Studies that run the pipeline: the paper's coding-efficiency table and curves."""
