"""py_depth_camera booted through its generated harness: the frames it
emits and the stream info it serves, as a consumer of depth_camera:v1 sees them."""

from peppygen.fixtures import harness
from peppygen.fixtures.exposed_services.depth_camera.v1 import video_stream_info

from py_depth_camera import setup

WAIT = 10.0


async def test_frames_and_stream_info_follow_the_parameters():
    async with harness.start(setup, parameters={"width": 8, "height": 4}) as h:
        frame = await h.emitted.depth_camera_video_stream.next(WAIT)
        assert (frame.encoding, frame.width, frame.height) == ("mono8", 8, 4)
        assert len(frame.frame) == 8 * 4
        following = await h.emitted.depth_camera_video_stream.next(WAIT)
        assert following.header.frame_id == frame.header.frame_id + 1

        # The tap's name in the Rust harness too (the topic alone, as no
        # other emitted topic is named so); both names tap the same topic.
        shared = await h.emitted.video_stream.next(WAIT)
        assert (shared.width, shared.height) == (8, 4)

        info = await video_stream_info.poll(h, WAIT)
        # The frame rate is the schema's default: only width and height were given.
        assert (info.width, info.height, info.frames_per_second, info.encoding) == (8, 4, 15, "mono8")
