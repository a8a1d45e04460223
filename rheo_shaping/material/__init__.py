"""Material models of the sheet (paper Sec. 3): the three-element model and its
closed forms (Eq. 1-8), the Burgers extension, responses to a load history.
Imports nothing else of the package.
"""
from .._lazy import lazy_api

__all__, __getattr__, __dir__ = lazy_api(__name__, {
    'three_element': ['ThreeElement', 'maxwell'],
    'burgers': ['Burgers'],
    'response': ['Response', 'elongation_response', 'force_response'],
})
