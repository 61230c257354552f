"""A vehicle's joint structure as data, from `nudyn describe MODEL --json`:
which entries of θ (qpos) and ν (qvel, ε) each joint owns. Scripts find
quaternions, hinges and translations here, never in the FMU's variable
descriptions, which are prose for people. Addresses are 0-based: FMU
variable theta[qpos_adr + 1] is a joint's first coordinate."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Joint:
    name: str
    body: str
    kind: str  # "hinge", "slide", "ball" or "free"
    qpos_adr: int
    nq: int
    dof_adr: int
    nv: int
    quaternion_adr: int | None  # θ index of its unit quaternion's w (ball and free joints)

    @property
    def qpos(self) -> range:
        return range(self.qpos_adr, self.qpos_adr + self.nq)

    @property
    def dofs(self) -> range:
        return range(self.dof_adr, self.dof_adr + self.nv)


@dataclass(frozen=True)
class VehicleStructure:
    name: str
    nq: int
    nv: int
    gravity: tuple[float, float, float]
    qpos0: tuple[float, ...]  # θ at the pose drawn in the file
    joints: tuple[Joint, ...]  # in MuJoCo's order, that of θ and ν

    @classmethod
    def from_json(cls, document: dict) -> VehicleStructure:
        return cls(
            name=document["name"],
            nq=document["nq"],
            nv=document["nv"],
            gravity=tuple(document["gravity"]),
            qpos0=tuple(document["qpos0"]),
            joints=tuple(Joint(**joint) for joint in document["joints"]),
        )

    @property
    def quaternion_starts(self) -> list[int]:
        """θ index of each unit quaternion's w (q and −q are one rotation)."""
        return [j.quaternion_adr for j in self.joints if j.quaternion_adr is not None]

    @property
    def translational_dofs(self) -> list[int]:
        """ν indices measured in m/s: a free joint's first three (its linear
        velocity) and each slide's."""
        dofs = []
        for joint in self.joints:
            if joint.kind == "free":
                dofs += joint.dofs[:3]
            elif joint.kind == "slide":
                dofs += joint.dofs
        return dofs
