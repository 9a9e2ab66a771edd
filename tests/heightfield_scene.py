"""A synthetic RGB-D camera over a height field (test helper): boxes, cylinders and baskets
standing on a table at z = 0, seen by a pinhole camera placed as the station's (1 m from
the table, 35° down), rendered by marching each pixel's ray until it meets the surface."""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from physcap_drake.perception.camera_geometry import CameraGeometry

#: Cell of the height field, m, and the part of the table it covers (x, y ranges, m).
CELL = 0.002
EXTENT = ((-0.05, 0.75), (-0.55, 0.55))
TABLE_RGB = (150, 150, 145)
#: Ray-marching step, m.
STEP = 0.002


def station_like_camera(width: int = 640, height: int = 360) -> CameraGeometry:
    """A camera at (-0.3, 0, 0.95) looking along +x, 55° below the horizontal."""
    down = np.arctan2(0.571, 0.821)  # the optical axis from the vertical, 35°
    c, s = np.cos(down), np.sin(down)
    rotation = RotationMatrix(np.array([[0.0, -c, s], [-1.0, 0.0, 0.0], [0.0, -s, -c]]))
    fx = 514.13 * width / 1280
    return CameraGeometry(width, height, fx, fx, (width - 1) / 2, (height - 1) / 2,
                          RigidTransform(rotation, [-0.3, 0.0, 0.95]))


class HeightfieldScene:
    """The surface's height (m) and colour per cell; shapes raise it where they stand."""

    def __init__(self):
        nx = int(round((EXTENT[0][1] - EXTENT[0][0]) / CELL))
        ny = int(round((EXTENT[1][1] - EXTENT[1][0]) / CELL))
        self.height = np.zeros((nx, ny))
        self.rgb = np.empty((nx, ny, 3), np.uint8)
        self.rgb[:] = TABLE_RGB
        xs = EXTENT[0][0] + CELL * (np.arange(nx) + 0.5)
        ys = EXTENT[1][0] + CELL * (np.arange(ny) + 0.5)
        self._x, self._y = np.meshgrid(xs, ys, indexing="ij")

    def _raise(self, where: np.ndarray, top: float, rgb) -> HeightfieldScene:
        self.height[where] = top
        self.rgb[where] = rgb
        return self

    def box(self, x: tuple[float, float], y: tuple[float, float], top: float, rgb):
        """An axis-aligned box over x[0]..x[1], y[0]..y[1] (m), `top` m high."""
        return self._raise((self._x >= x[0]) & (self._x <= x[1]) & (self._y >= y[0])
                           & (self._y <= y[1]), top, rgb)

    def cylinder(self, x: float, y: float, radius: float, top: float, rgb):
        """An upright cylinder (a cup) standing at (x, y) on what is under it (m)."""
        where = np.hypot(self._x - x, self._y - y) <= radius
        return self._raise(where, float(self.height[where].max()) + top, rgb)

    def basket(self, x: tuple[float, float], y: tuple[float, float], wall: float,
               top: float, floor: float, rgb):
        """An open box: a floor `floor` thick, walls `wall` thick and `top` high (m)."""
        self.box(x, y, top, rgb)
        return self.box((x[0] + wall, x[1] - wall), (y[0] + wall, y[1] - wall), floor, rgb)

    def images(self, camera: CameraGeometry,
               noise: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(colour image H × W × 3 uint8, depth image H × W, m along the optical axis);
        the depth with Gaussian noise of `noise` m RMS (seeded: the same every time)."""
        v, u = np.mgrid[0:camera.height, 0:camera.width]
        rays_c = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy,
                           np.ones(u.shape)], axis=-1).reshape(-1, 3)
        rotation = camera.X_WC.rotation().matrix()
        origin = camera.X_WC.translation()
        rays = rays_c @ rotation.T  # world direction per unit of depth
        ceiling = float(self.height.max()) + 0.01
        start = (origin[2] - ceiling) / -rays[:, 2]
        end = origin[2] / -rays[:, 2]
        depth = end.copy()  # where the ray meets the table
        table = origin + rays * end[:, None]
        open_ = ((table[:, 0] > EXTENT[0][0] - 0.3) & (table[:, 0] < EXTENT[0][1] + 0.3)
                 & (table[:, 1] > EXTENT[1][0] - 0.3) & (table[:, 1] < EXTENT[1][1] + 0.3))
        length = np.linalg.norm(rays, axis=1)
        steps = np.max(((end - start) * length)[open_]) / STEP
        for step in range(int(np.ceil(steps)) + 1):
            t = start + step * STEP / length
            live = open_ & (t < end)
            if not live.any():
                break
            point = origin + rays[live] * t[live, None]
            ix = np.floor((point[:, 0] - EXTENT[0][0]) / CELL).astype(int)
            iy = np.floor((point[:, 1] - EXTENT[1][0]) / CELL).astype(int)
            inside = (ix >= 0) & (ix < self.height.shape[0]) & (iy >= 0) & (
                iy < self.height.shape[1])
            surface = np.zeros(len(point))
            surface[inside] = self.height[ix[inside], iy[inside]]
            hit = point[:, 2] <= surface
            index = np.flatnonzero(live)[hit]
            depth[index] = t[live][hit]
            open_[index] = False
        points = origin + rays * depth[:, None]
        ix = np.clip(np.floor((points[:, 0] - EXTENT[0][0]) / CELL).astype(int), 0,
                     self.height.shape[0] - 1)
        iy = np.clip(np.floor((points[:, 1] - EXTENT[1][0]) / CELL).astype(int), 0,
                     self.height.shape[1] - 1)
        rgb = np.where(((points[:, 0] >= EXTENT[0][0]) & (points[:, 0] < EXTENT[0][1])
                        & (points[:, 1] >= EXTENT[1][0]) & (points[:, 1] < EXTENT[1][1]))[:, None],
                       self.rgb[ix, iy], np.array(TABLE_RGB, np.uint8))
        shape = (camera.height, camera.width)
        depth = depth + np.random.default_rng(0).normal(0.0, noise, depth.shape)
        return rgb.reshape(*shape, 3).astype(np.uint8), depth.reshape(shape)
