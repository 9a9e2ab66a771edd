"""Intel RealSense D400-series cameras through librealsense (`pyrealsense2`, the optional
extra `realsense`): a live device or a `.db3` recording through `rs.pipeline`, and an
emulated camera fed with rendered frames through librealsense's software device. All of
them end in the same frame path (`frames.frame_from_frameset`) and a LeafSystem exporting
`<name>.rgb` and `<name>.depth` with the station's image types.

`config` (the scenario entry) and `depth_faults` (the stereo error model) need no
pyrealsense2; everything that talks to librealsense imports it through `librealsense()`.
"""
