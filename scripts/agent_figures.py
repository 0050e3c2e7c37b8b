"""Draw docs/images/agent_figures.png: every cohabitant kind's low-poly figure (sim/agents/figures.py) on a grey ground."""

import numpy as np
import pybullet as p
from PIL import Image

from sim.agents.figures import figure_shape
from sim.agents.kinds import AGENT_KINDS

c = p.connect(p.DIRECT)
col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[20, 20, 0.5])
vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[20, 20, 0.5], rgbaColor=[0.7, 0.7, 0.7, 1])
p.createMultiBody(0, col, vis, [0, 0, -0.5])
for i, (k, kind) in enumerate(AGENT_KINDS.items()):
    h = max(kind.height, 2 * kind.radius)
    v = figure_shape(c, k, h, kind.radius, kind.color)
    p.createMultiBody(0, -1, v, [0, (i - 3) * 1.2, h / 2], p.getQuaternionFromEuler([0, 0, 0.5]))
view = p.computeViewMatrix([6, 0, 2.0], [0, 0, 0.8], [0, 0, 1])
proj = p.computeProjectionMatrixFOV(60, 2, 0.1, 50)
_, _, rgb, _, _ = p.getCameraImage(800, 400, view, proj, renderer=p.ER_TINY_RENDERER)
Image.fromarray(np.asarray(rgb, np.uint8).reshape(400, 800, 4)[:, :, :3]).save("docs/images/agent_figures.png")
