"""A campaign as written: its file read with positions, checked against its FMU, and the
uncertain values each run draws (``load``, ``validation_errors``, ``campaign_values``,
``schema``, ``field_types``, ``environment_section``, ``distributions``, ``expectations``,
``yamlsource``, ``environment``, ``areas``, ``sampling``, ``validate``, ``parameter_checks``,
``terrain_checks``, ``fmu_checks``, ``fmu_variable_checks``, ``signal_map_checks``,
``chain_checks``, ``waivers``). The read side of stored campaigns (``idefix_rules.results``)
rebuilds a campaign with these modules only."""
