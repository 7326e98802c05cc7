"""Authenticated, access-controlled deployments.

:mod:`~openptrack_py.security.pki` makes a site's certificate authority and the
certificates of its nodes (``openptrack certs``); :mod:`~openptrack_py.security.policy`
turns a network file's ``security`` section into the Zenoh settings every session
opens with: mutual TLS with the node's own certificate, and the access-control list
that says which certificate may put on which key.
"""
