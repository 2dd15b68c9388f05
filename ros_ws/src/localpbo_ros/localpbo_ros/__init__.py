"""localpbo ROS 2 nodes: thin glue around localpbo_core, localpbo_sims and localpbo_msgs_py."""
