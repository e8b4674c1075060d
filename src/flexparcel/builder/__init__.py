"""The builder: compiles element groups, rigid links and contact sets into a Model."""

from flexparcel.builder.model_builder import ModelBuilder

__all__ = ["ModelBuilder"]
