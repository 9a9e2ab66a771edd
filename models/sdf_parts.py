"""SDF pieces shared by the model generators in models/*/generate_*.py (plain Python)."""

#: Point-contact stiffness of every free object, N/m. Without it Drake derives one from the
#: body's weight and the plant's penetration allowance (130 N/m for 13 g), and the fingers
#: would sink through a light object.
POINT_STIFFNESS = "          <drake:point_contact_stiffness>1e5</drake:point_contact_stiffness>\n"


def cylinder_inertia(mass: float, radius: float, height: float) -> tuple[float, float, float]:
    """Solid cylinder about its COM (z along the axis), kg·m²."""
    side = mass * (3 * radius**2 + height**2) / 12.0
    return side, side, mass * radius**2 / 2.0


def ellipsoid_inertia(mass: float, a: float, b: float, c: float) -> tuple[float, float, float]:
    """Solid ellipsoid with semi-axes a, b, c (m) about its COM, kg·m²."""
    return mass * (b**2 + c**2) / 5.0, mass * (a**2 + c**2) / 5.0, mass * (a**2 + b**2) / 5.0


#: Mesh resolution hint of the avocados' compliant ellipsoids, m. Drake refines an ellipsoid's
#: tetrahedral mesh in whole levels: 0.01 gives 512 tetrahedra, 0.005 gave 2,048. A squeeze's
#: contact surfaces have about one polygon per tetrahedron a pad cuts, and each polygon is a
#: contact constraint the plant builds and solves every step: at 0.005 a ripe avocado squeezed
#: 11 mm gave about 1,000 of them; at 0.01 a pick_ripe_avocado episode takes about 30 % less
#: CPU time. The squeeze depths the stiffness probe measures move by up to about 0.7 mm on
#: the soft avocados and 0.1 mm on the firm ones; every avocado keeps its level (README, Speed).
AVOCADO_MESH_RESOLUTION = 0.01


def compliant(modulus: float, mesh_resolution: float = 0.005) -> str:
    """Proximity properties of a compliant-hydroelastic body of `modulus` Pa whose
    tetrahedral mesh is refined to about `mesh_resolution` m."""
    return ("          <drake:compliant_hydroelastic/>\n"
            f"          <drake:hydroelastic_modulus>{modulus:g}</drake:hydroelastic_modulus>\n"
            f"          <drake:mesh_resolution_hint>{mesh_resolution:g}"
            "</drake:mesh_resolution_hint>\n"
            "          <drake:hunt_crossley_dissipation>5</drake:hunt_crossley_dissipation>\n"
            + POINT_STIFFNESS)
