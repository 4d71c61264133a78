"""The evaluation stage: the stored runs scored under the compiled rulebook (``evaluate``),
each path judged with the campaign's α budget (``scoring``), the assumed slip against the
simulated one (``slip``) and the parameters that drive a path's risk (``sensitivity``)."""
