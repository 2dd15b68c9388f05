"""Worked examples for localpbo: controllers that know nothing of localpbo, tuned from outside."""
