# SPDX-License-Identifier: Apache-2.0
"""What a person watches: the route, the match and the home vector as markers, an overlay image, confidence and state.

`scene` (the markers' geometry from the map's poses) and `overlay` (the drawn image) are the plain numpy/OpenCV
core (no ROS); `node` publishes them in standard types under /skynav/viz (docs/interfaces.md, "Visualization").
"""
