"""A bag replayed without --odom runs the matcher without odometry (constant velocity), and says so in the
configuration the field log records (so the log's replay agrees)."""

from __future__ import annotations

import argparse

from app.replay import bag_estimator_config
from vipsm.estimator import EstimatorConfig


def _args(odom: str | None) -> argparse.Namespace:
    return argparse.Namespace(odom=odom, laser_x=None, laser_y=None, laser_yaw_deg=None)


def test_no_odometry_topic_means_constant_velocity() -> None:
    assert bag_estimator_config(EstimatorConfig(), _args(None)).motion_prior == "constant_velocity"
    assert bag_estimator_config(EstimatorConfig(), _args("/odom")).motion_prior == "odometry"
