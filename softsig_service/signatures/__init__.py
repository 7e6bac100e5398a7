"""The signatures as pure math (numpy, no MuJoCo): the closure signature by three methods, the grasp-stiffness
algebra, marker files. The checked-matrix helpers the algebra uses stay in
:mod:`softsig_service.signatures.matrix_checks`."""

from softsig_service.signatures.capture import CaptureModel, agreement, theta_axis, uniform_axis, wrap_theta
from softsig_service.signatures.closure import (
    check_criterion,
    compute_closure_signature,
    distinctness_ratio,
    ellipsoid_axis_series,
    ellipsoid_closure_signature,
    mesh_closure_signature,
    pca_closure_signature,
)
from softsig_service.signatures.closure_types import ClosureSignature, EllipsoidAxisSeries
from softsig_service.signatures.markers import load_markers, parse_markers_csv, parse_markers_json
from softsig_service.signatures.stiffness import (
    constraint_basis,
    contact_space_stiffness,
    contact_stiffness_matrix,
    grasp_matrix,
    grasp_stiffness,
    grasp_stiffness_terms,
    hand_quadratic,
    principal_stiffness,
    principal_stiffnesses,
    skew,
    stiffness_ellipsoid,
)
from softsig_service.signatures.stiffness_types import (
    BreakForce,
    ContactRecord,
    PrincipalStiffness,
    StiffnessSignature,
    StiffnessTerms,
)

__all__ = [
    "BreakForce",
    "CaptureModel",
    "ClosureSignature",
    "ContactRecord",
    "EllipsoidAxisSeries",
    "PrincipalStiffness",
    "StiffnessSignature",
    "StiffnessTerms",
    "agreement",
    "check_criterion",
    "compute_closure_signature",
    "constraint_basis",
    "contact_space_stiffness",
    "contact_stiffness_matrix",
    "distinctness_ratio",
    "ellipsoid_axis_series",
    "ellipsoid_closure_signature",
    "grasp_matrix",
    "grasp_stiffness",
    "grasp_stiffness_terms",
    "hand_quadratic",
    "load_markers",
    "mesh_closure_signature",
    "parse_markers_csv",
    "parse_markers_json",
    "pca_closure_signature",
    "principal_stiffness",
    "principal_stiffnesses",
    "skew",
    "stiffness_ellipsoid",
    "theta_axis",
    "uniform_axis",
    "wrap_theta",
]
