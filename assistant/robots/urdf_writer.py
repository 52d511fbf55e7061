"""Write a URDF for a DH-described robot so pinocchio and URDF viewers see the same arm.

Joint i's origin is the fixed part F_(i-1) of the previous DH row, its axis is z, and link i's
frame is the one `dh.chain_frames` returns - so link shapes need no conversion. URDF has no
capsule, so a capsule is written as a cylinder with two spheres.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from assistant.robots.dh import DHChain
from assistant.robots.model import CollisionShape, JointLimits, LinkGeometry, ShapeKind
from assistant.transforms import matrix_to_rpy

Array = np.ndarray


def _origin(T: Array) -> str:
    r, p, y = matrix_to_rpy(T[:3, :3])[::-1]  # URDF rpy = (roll about x, pitch y, yaw z)
    x, yv, z = T[:3, 3]
    return f'<origin xyz="{x:.9f} {yv:.9f} {z:.9f}" rpy="{r:.12f} {p:.12f} {y:.12f}"/>'


def _shape_elements(tag: str, shape: CollisionShape, rgba: str | None) -> list[str]:
    material = f'<material name="m"><color rgba="{rgba}"/></material>' if rgba else ""
    T = shape.T_link_shape
    if shape.kind == ShapeKind.CAPSULE:
        r, length = shape.size
        out = [f"<{tag}>{_origin(T)}<geometry><cylinder radius=\"{r:.6f}\" "
               f"length=\"{length:.6f}\"/></geometry>{material}</{tag}>"]
        for sgn in (-1.0, 1.0):
            Ts = T.copy()
            Ts[:3, 3] = T[:3, 3] + sgn * length / 2.0 * T[:3, 2]
            out.append(f"<{tag}>{_origin(Ts)}<geometry><sphere radius=\"{r:.6f}\"/></geometry>"
                       f"{material}</{tag}>")
        return out
    if shape.kind == ShapeKind.CYLINDER:
        geom = f'<cylinder radius="{shape.size[0]:.6f}" length="{shape.size[1]:.6f}"/>'
    elif shape.kind == ShapeKind.BOX:
        geom = '<box size="{:.6f} {:.6f} {:.6f}"/>'.format(*shape.size)
    elif shape.kind == ShapeKind.SPHERE:
        geom = f'<sphere radius="{shape.size[0]:.6f}"/>'
    else:
        return []  # meshes would need files beside the URDF; drawn from `links` instead
    return [f"<{tag}>{_origin(T)}<geometry>{geom}</geometry>{material}</{tag}>"]


def urdf_from_chain(
    name: str,
    chain: DHChain,
    joint_names: list[str],
    limits: JointLimits,
    links: list[LinkGeometry],
    T_flange_tool: Array,
) -> str:
    """A self-contained URDF string: base, one link per joint, flange and tool frames."""
    parts = [f'<?xml version="1.0"?>\n<robot name={quoteattr(name)}>']
    for link in links:
        rgba = " ".join(f"{c / 255:.3f}" for c in link.color) + " 1"
        body = []
        for s in link.collision:
            body += _shape_elements("visual", s, rgba)
            body += _shape_elements("collision", s, None)
        parts.append(f"<link name={quoteattr(link.name)}>{''.join(body)}</link>")
    prev_T = np.eye(4)
    for i, jn in enumerate(joint_names):
        parent, child = links[i].name, links[i + 1].name
        parts.append(
            f'<joint name={quoteattr(jn)} type="revolute">{_origin(prev_T)}'
            f"<parent link={quoteattr(parent)}/><child link={quoteattr(child)}/>"
            f'<axis xyz="0 0 1"/><limit lower="{limits.lower[i]:.9f}" '
            f'upper="{limits.upper[i]:.9f}" velocity="{limits.velocity[i]:.6f}" effort="100"/>'
            "</joint>"
        )
        prev_T = chain.fixed_part(i)
    last = links[len(joint_names)].name
    parts.append('<link name="flange"/><link name="tool"/>')
    parts.append(f'<joint name="flange_fixed" type="fixed">{_origin(prev_T)}'
                 f'<parent link={quoteattr(last)}/><child link="flange"/></joint>')
    parts.append(f'<joint name="tool_fixed" type="fixed">{_origin(T_flange_tool)}'
                 '<parent link="flange"/><child link="tool"/></joint>')
    parts.append("</robot>")
    return "\n".join(parts)
