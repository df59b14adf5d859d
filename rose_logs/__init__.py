"""rose-bag: ROSE over robot logs (ROS 1 bags, ROS 2 bags, MCAP), Rerun views and cleaned output bags."""

__version__ = "0.1.0"
