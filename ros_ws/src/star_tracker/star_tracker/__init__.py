"""Star-camera pipeline (paper 003, SCENARIOS.md §4): the real sky (catalogue), a pinhole star camera, k-vector
and Pyramid lost-in-space identification, TRIAD and Wahba attitude, image-plane motion models, SNA and JPDAF
star tracking. No module of the core imports rclpy."""
