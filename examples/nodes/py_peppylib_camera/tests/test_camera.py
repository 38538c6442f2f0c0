"""py_peppylib_camera booted through its generated harness: frames stamped by
the stack clock, and the stream info it serves, as a consumer of
depth_camera:v1 sees them."""

import time

from peppygen.fixtures import harness
from peppygen.fixtures.exposed_services.camera import video_stream_info

from py_peppylib_camera.__main__ import setup

WAIT = 10.0


async def test_frames_are_stamped_by_the_wall_clock_and_shaped_by_the_defaults():
    async with harness.start(setup) as h:
        before = time.time()
        frame = await h.emitted.camera_video_stream.next(WAIT)
        assert (frame.encoding, frame.width, frame.height) == ("mono8", 64, 48)
        assert len(frame.frame) == 64 * 48
        # Wall mode: the node's clock is this host's.
        assert before - WAIT <= frame.header.stamp <= time.time()

        info = await video_stream_info.poll(h, WAIT)
        assert (info.width, info.height, info.frames_per_second) == (64, 48, 15)
        assert h.setup_finished()


async def test_parameters_given_replace_the_defaults():
    async with harness.start(setup, parameters={"width": 4, "height": 2}) as h:
        frame = await h.emitted.camera_video_stream.next(WAIT)
        assert (frame.width, frame.height, len(frame.frame)) == (4, 2, 8)
