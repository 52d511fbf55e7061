"""3-D position of the ball from pixels: the exact sphere-centre ray, stereo triangulation with
covariance, and the single-camera estimate from the ball's known size.

A sphere does not image to a circle centred on the projection of its centre: off the optical
axis it images to an ellipse whose centre lies slightly further out. `sphere_ray` undoes that
exactly (a few hundredths of a pixel for our ball, but it costs nothing) and turns the blob's
area into the cone half-angle, which gives the distance in single-camera mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision.camera_model import CameraModel


@dataclass(frozen=True)
class SphereRay:
    """The ray from a camera's optical centre through a ball's centre, in the world frame."""

    origin_world: np.ndarray
    direction_world: np.ndarray  # unit
    half_angle: float  # angular radius of the ball seen from the camera (radians)
    normalized: np.ndarray  # (2,) ideal normalised image point of the centre (x/z, y/z)


def sphere_ray(model: CameraModel, center_px: np.ndarray, radius_px: float) -> SphereRay:
    """Ray through the ball centre from a blob's area centroid and equivalent radius.

    A cone of half-angle a whose axis is theta off the optical axis cuts the normalised image
    plane in an ellipse with centre offset rho = sin(t)cos(t) / (cos^2 t - sin^2 a) and area
    pi sin^2(a) cos(a) / (cos^2 t - sin^2 a)^1.5; both are solved for (theta, a) here.
    """
    n = model.normalized(np.asarray(center_px, dtype=float)[None])[0]
    rho_c = float(np.hypot(n[0], n[1]))
    phi = float(np.arctan2(n[1], n[0]))
    area_n = np.pi * radius_px**2 / (model.K[0, 0] * model.K[1, 1])
    theta = float(np.arctan(rho_c))
    alpha = float(np.sqrt(area_n / np.pi)) * np.cos(theta) ** 1.5  # first guess
    if alpha > 0:
        for _ in range(4):
            alpha = _solve_alpha(area_n, theta, alpha)
            theta = _solve_theta(rho_c, alpha, theta)
    d_cam = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    R = model.T_world_camera[:3, :3]
    return SphereRay(model.position_world, R @ d_cam, float(alpha), d_cam[:2] / d_cam[2])


def _ellipse_area(theta: float, alpha: float) -> float:
    den = np.cos(theta) ** 2 - np.sin(alpha) ** 2
    return float(np.pi * np.sin(alpha) ** 2 * np.cos(alpha) / max(den, 1e-12) ** 1.5)


def _solve_alpha(area_n: float, theta: float, alpha: float) -> float:
    for _ in range(3):
        h = 1e-7 * max(alpha, 1e-6)
        f0 = _ellipse_area(theta, alpha) - area_n
        df = (_ellipse_area(theta, alpha + h) - _ellipse_area(theta, alpha - h)) / (2 * h)
        if df <= 0:
            break
        alpha = float(np.clip(alpha - f0 / df, 1e-9, np.pi / 2 - 1e-6))
    return alpha


def _solve_theta(rho_c: float, alpha: float, theta: float) -> float:
    s2 = np.sin(alpha) ** 2
    for _ in range(3):
        c2 = np.cos(theta) ** 2
        g = np.sin(theta) * np.cos(theta) / (c2 - s2) - rho_c
        h = 1e-7
        g2 = np.sin(theta + h) * np.cos(theta + h) / (np.cos(theta + h) ** 2 - s2) - rho_c
        dg = (g2 - g) / h
        if dg <= 0:
            break
        theta -= g / dg
    return float(theta)


@dataclass(frozen=True)
class PointEstimate:
    """A 3-D ball position from one frame set, with its covariance and how well views agree."""

    position_world: np.ndarray
    covariance: np.ndarray
    mode: str  # "stereo" or "mono"
    reprojection_px: float  # RMS over the cameras used (0 for mono)
    cameras: tuple[int, ...]  # indices of the cameras used


def _project_jacobian(model: CameraModel, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ideal-pixel projection (f x/z, f y/z) of X and its 2x3 Jacobian w.r.t. X (world)."""
    T = model.T_camera_world
    Pc = T[:3, :3] @ X + T[:3, 3]
    fx, fy = model.K[0, 0], model.K[1, 1]
    z = Pc[2]
    uv = np.array([fx * Pc[0] / z, fy * Pc[1] / z])
    J = np.array([[fx / z, 0.0, -fx * Pc[0] / z**2], [0.0, fy / z, -fy * Pc[1] / z**2]])
    return uv, J @ T[:3, :3]


def triangulate(models: list[CameraModel], rays: list[SphereRay],
                sigma_px: float = 0.3, iterations: int = 3) -> PointEstimate | None:
    """Least-squares point of two or more rays, refined on reprojection error (Gauss-Newton).

    The covariance is sigma_px^2 (J^T J)^-1 at the solution: first-order propagation of the
    centre's pixel noise, so it is small across the rays and long along them when they meet at
    a shallow angle. None if the rays are (nearly) parallel or the point is behind a camera.
    """
    if len(models) < 2 or len(models) != len(rays):
        raise ValueError("triangulation needs two or more cameras with one ray each")
    # linear start: the point closest to all rays
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for r in rays:
        P = np.eye(3) - np.outer(r.direction_world, r.direction_world)
        A += P
        b += P @ r.origin_world
    if np.linalg.cond(A) > 1e8:
        return None
    X = np.linalg.solve(A, b)
    targets = [np.array([m.K[0, 0] * r.normalized[0], m.K[1, 1] * r.normalized[1]])
               for m, r in zip(models, rays, strict=True)]
    for _ in range(iterations):
        JtJ = np.zeros((3, 3))
        Jtr = np.zeros(3)
        for m, tgt in zip(models, targets, strict=True):
            uv, J = _project_jacobian(m, X)
            res = tgt - uv
            JtJ += J.T @ J
            Jtr += J.T @ res
        try:
            step = np.linalg.solve(JtJ, Jtr)
        except np.linalg.LinAlgError:
            return None
        X = X + step
        if np.linalg.norm(step) < 1e-9:
            break
    JtJ = np.zeros((3, 3))
    sq = 0.0
    for m, tgt in zip(models, targets, strict=True):
        if (m.to_camera(X)[0, 2]) <= 0:
            return None
        uv, J = _project_jacobian(m, X)
        sq += float(np.sum((tgt - uv) ** 2))
        JtJ += J.T @ J
    try:
        cov = sigma_px**2 * np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return None
    return PointEstimate(X, cov, "stereo", float(np.sqrt(sq / len(models))), ())


def mono_from_size(model: CameraModel, ray: SphereRay, ball_radius: float,
                   sigma_px: float = 0.3, sigma_radius_px: float = 0.3) -> PointEstimate:
    """Single camera: the distance to the centre is R / sin(half-angle). Less accurate: a
    0.1 px error in a 7 px radius is 1.4 % of the distance, so say so wherever it is shown."""
    alpha = max(ray.half_angle, 1e-6)
    D = ball_radius / np.sin(alpha)
    X = ray.origin_world + D * ray.direction_world
    f = model.focal_px
    sigma_lat = D * sigma_px / f
    sigma_alpha = sigma_radius_px / f
    sigma_d = ball_radius * np.cos(alpha) / np.sin(alpha) ** 2 * sigma_alpha
    d = ray.direction_world
    cov = sigma_lat**2 * (np.eye(3) - np.outer(d, d)) + sigma_d**2 * np.outer(d, d)
    return PointEstimate(X, cov, "mono", 0.0, ())


def expected_radius_px(model: CameraModel, point_world: np.ndarray, ball_radius: float) -> float:
    """Apparent radius of a ball of `ball_radius` centred at `point_world`."""
    D = float(np.linalg.norm(model.to_camera(point_world)[0]))
    if D <= ball_radius:
        return float("inf")
    return float(model.focal_px * np.tan(np.arcsin(ball_radius / D)))


def project_covariance(model: CameraModel, X: np.ndarray, cov_world: np.ndarray) -> np.ndarray:
    """2x2 pixel covariance of the projection of a 3-D Gaussian (first order)."""
    _, J = _project_jacobian(model, X)
    return J @ cov_world @ J.T
