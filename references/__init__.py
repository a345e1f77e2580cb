"""The scene families: each module is one home for its named scenes, their references (fields, scalars, the
history curve) and the contract of the summary scalars its solvers report (`heat`, `lattice`, `elastic`,
`contact`; what they share in `shared`).  `SCENES` lists every shipped scene spec; the harness asks a spec for its
reference and names no scene.
"""

from __future__ import annotations

from pcverify.references import contact, elastic, heat, lattice
from pcverify.scene import SceneSpec

SCENES: tuple[SceneSpec, ...] = (*heat.SCENES, *lattice.SCENES, *elastic.SCENES, *contact.SCENES)
