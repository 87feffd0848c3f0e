"""The domain-free engine: relations, verdicts, matching, the ``@metamorphic`` decorator."""
