(* a function block a C library implements: only its declaration is here *)
FUNCTION_BLOCK LowPass
	VAR_INPUT
		In : REAL;
	END_VAR
	VAR_OUTPUT
		Out : REAL;
	END_VAR
END_FUNCTION_BLOCK
