"""Benchmarks that need ROS: transport per duel and codec/recording cost per message.

Benchmarks of the core (surrogate, algorithms, threads, episodes) live in
``localpbo_core.benchmarks``. Each prints figures and asserts nothing.
"""
