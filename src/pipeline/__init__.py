"""Pipeline: experiments, stage caches, the sweep, capture folders and ROS bags."""
