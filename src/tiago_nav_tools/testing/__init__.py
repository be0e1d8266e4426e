"""Test doubles and test/benchmark support, shipped apart from the product (as
``py_trees_ros.mock`` is): product modules never import this package.

Doubles behave like the real thing they stand for, failures included: a fake of a service that
answers ``success: false`` answers ``success: false``; it does not raise.
"""
