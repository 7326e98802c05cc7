"""Node processes, one thin module each: ``python -m openptrack_py.nodes.<name>``.

Every node is also ``openptrack node <name>``; ``openptrack launch`` starts the ones a
network file asks for on this host.
"""
