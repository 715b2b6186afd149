"""ROS 1/2 bags and MCAP files: their topics, message fields and vendors, read into streams
by a plain :class:`~graphcal.recording.bag.request.BagRequest`."""
