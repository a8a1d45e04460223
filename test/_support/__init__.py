"""Helpers shared by the tests (not test modules: pytest collects nothing here).

``stages`` splits the suite between the two virtualenvs (dev.py reads it too),
``domains`` claims a private ROS_DOMAIN_ID, ``cells`` builds the cells the tests run,
``packaging`` reads setup.py, ``ros`` and ``rigs`` hold the ROS 2 helpers (they need rclpy).
"""
