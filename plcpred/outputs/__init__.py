"""What plcpred writes for people: the files of a prediction or an emulation
(:mod:`~plcpred.outputs.files`) and the plots and reports (:mod:`~plcpred.outputs.report`).
The models below expose data; this layer turns it into files, each written through a
temporary file (:mod:`plcpred.output`)."""
