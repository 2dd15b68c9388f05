"""localpbo core: the math of local preferential Bayesian optimization (no ROS here)."""
