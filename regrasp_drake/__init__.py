"""regrasp-drake: regrasp planning through throwing and catching, in Drake."""

__version__ = "0.1.0"
