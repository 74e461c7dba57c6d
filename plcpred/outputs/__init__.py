"""What plcpred writes for people: the files of a prediction or an emulation
(:mod:`~plcpred.outputs.files`), the demand plot and table
(:mod:`~plcpred.outputs.demand_plot`), the sizing report
(:mod:`~plcpred.outputs.sizing_report`), the emulation's plot
(:mod:`~plcpred.outputs.emulation_plot`) and the diagnosis report
(:mod:`~plcpred.outputs.diagnosis_report`), on what every plot shares
(:mod:`~plcpred.outputs.plotting`). The models below expose data; this layer turns it
into files, each written through a temporary file (:mod:`plcpred.output`)."""
