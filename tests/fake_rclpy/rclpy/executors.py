"""``rclpy.executors.ExternalShutdownException``: what spinning a shut-down context raises."""


class ExternalShutdownException(Exception):
    pass
