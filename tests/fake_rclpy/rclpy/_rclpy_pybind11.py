"""``rclpy._rclpy_pybind11.RCLError``: what rcl's failures raise (a RuntimeError)."""


class RCLError(RuntimeError):
    pass
