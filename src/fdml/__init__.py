"""fdml: frequency-domain maximum-likelihood identification of the short period."""

__version__ = "0.1.0"
