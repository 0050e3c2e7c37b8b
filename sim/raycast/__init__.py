"""Static LiDAR without Bullet: a scene's static solids as distance grids (`grids`) and the rays' march (`march`).

Both envs use it: the PyBullet env's `sim.sensors.GridLidar` for one machine, the batched env's `sim.batched.lidar`
for many. docs/raycast.md says how it is built and how far it is from Bullet's ray test.
"""
