"""Identification of the material's parameters from creep and tensile
tests (paper Sec. 3.4, Eq. 10-13), the joint fit with model choice by
AIC/BIC, the material CSV files and synthetic test curves.
Imports :mod:`rheo_shaping.material`.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'paper_method': ['PaperIdentification', 'identify_paper'],
    'model_choice': ['JointIdentification', 'identify_joint'],
    'material_data': ['DataFormatError', 'read_material_file'],
})
