"""rclpy's logger with the cheap caller lookup: the same call-site ids, filters unchanged."""

from __future__ import annotations

from activesurv_common.ros import fast_logging


def test_the_caller_id_is_the_call_site() -> None:
    import rclpy.impl.rcutils_logger as impl

    assert fast_logging.install()

    def here() -> impl.CallerId:
        return impl.CallerId()

    cid = here()
    assert cid.function_name == 'here'
    assert cid.file_path == here.__code__.co_filename
    assert cid.line_number == here.__code__.co_firstlineno + 1
    assert here() == cid  # the same site: the same id (the filters' key)


def test_throttle_and_once_still_filter() -> None:
    import rclpy.logging

    assert fast_logging.install()
    log = rclpy.logging.get_logger('fast_logging_test')
    said = [log.info('throttled', throttle_duration_sec=60.0) for _ in range(3)]
    assert said == [True, False, False]
    said = [log.info('once', once=True) for _ in range(2)]
    assert said == [True, False]
