"""Sensor models and nodes: ground radar and inter-satellite range/azimuth/elevation, relative position."""
