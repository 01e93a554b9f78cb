"""Bridges to CAD hosts, installed as gsr_cad.exporters; nothing else in gsr_cad imports them."""
